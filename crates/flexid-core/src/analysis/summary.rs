use crate::identify::fit::ChainFit;
use crate::model::{Chain, SampledChain};
use serde::Serialize;

/// One compliant coupling of the identified chain and the resonance it causes.
#[derive(Debug, Clone, Serialize)]
pub struct Coupling {
    /// 1-based index i: the spring between body i and body i+1 (body 1 is the motor).
    pub index: usize,
    /// Stiffness [N m/rad] and its one-sigma uncertainty.
    pub stiffness_nm_per_rad: f64,
    pub stiffness_std_nm_per_rad: f64,
    /// The resonance [Hz] whose mode stores the largest share of its strain energy in this
    /// spring, and that share [0..1].
    pub resonance_hz: f64,
    pub strain_energy_share: f64,
}

/// The identified model as reported and published (`"model"` object of the JSON output).
#[derive(Debug, Clone, Serialize)]
pub struct ModelSummary {
    pub masses: usize,
    /// `J1..Jn` [kg m^2], motor first, and their one-sigma uncertainties.
    pub inertia_kgm2: Vec<f64>,
    pub inertia_std_kgm2: Vec<f64>,
    /// `c1..c(n-1)` [N m/rad] and uncertainties.
    pub stiffness_nm_per_rad: Vec<f64>,
    pub stiffness_std_nm_per_rad: Vec<f64>,
    /// `d1..d(n-1)` [N m s/rad] and uncertainties.
    pub damping_nms_per_rad: Vec<f64>,
    pub damping_std_nms_per_rad: Vec<f64>,
    /// Undamped resonances of the identified chain [Hz], ascending.
    pub resonance_hz: Vec<f64>,
    /// Undamped anti-resonances (motor locked) [Hz], ascending.
    pub antiresonance_hz: Vec<f64>,
    /// Damping ratio of each mode [-], in the order of `resonance_hz`.
    pub damping_ratio: Vec<f64>,
    /// Total inertia [kg m^2].
    pub total_inertia_kgm2: f64,
    /// Where the compliant couplings are, softest-mode first.
    pub couplings: Vec<Coupling>,
}

impl ModelSummary {
    /// Summarise a fit; `sc` is the fitted chain's sampled model (for the modal damping).
    pub fn new(fit: &ChainFit, sc: &SampledChain) -> Self {
        let ch = &fit.chain;
        let resonance_hz = ch.resonances_hz();
        // modal damping from the continuous poles (upper half plane), matched by frequency
        let mut poles: Vec<(f64, f64)> = sc
            .poles()
            .iter()
            .filter(|p| p.im >= 0.0)
            .map(|p| (p.norm() / (2.0 * std::f64::consts::PI), -p.re / p.norm()))
            .collect();
        poles.sort_by(|a, b| a.0.total_cmp(&b.0));
        let damping_ratio = resonance_hz
            .iter()
            .map(|f| {
                poles
                    .iter()
                    .min_by(|a, b| (a.0 - f).abs().total_cmp(&(b.0 - f).abs()))
                    .map_or(f64::NAN, |p| p.1)
            })
            .collect();
        let couplings = couplings(ch, &fit.std.stiffness_nm_per_rad);
        ModelSummary {
            masses: ch.masses(),
            inertia_kgm2: ch.inertia_kgm2.clone(),
            inertia_std_kgm2: fit.std.inertia_kgm2.clone(),
            stiffness_nm_per_rad: ch.stiffness_nm_per_rad.clone(),
            stiffness_std_nm_per_rad: fit.std.stiffness_nm_per_rad.clone(),
            damping_nms_per_rad: ch.damping_nms_per_rad.clone(),
            damping_std_nms_per_rad: fit.std.damping_nms_per_rad.clone(),
            antiresonance_hz: ch.antiresonances_hz(),
            resonance_hz,
            damping_ratio,
            total_inertia_kgm2: ch.total_inertia(),
            couplings,
        }
    }
}

/// For every undamped mode, the spring holding most of its strain energy
/// `c_i (phi_(i+1) - phi_i)^2`: that coupling is the compliance behind the resonance.
fn couplings(ch: &Chain, std: &[f64]) -> Vec<Coupling> {
    let n = ch.masses();
    if n < 2 {
        return Vec::new();
    }
    let j = &ch.inertia_kgm2;
    let c = &ch.stiffness_nm_per_rad;
    // mass-normalised stiffness K~ = M^-1/2 K M^-1/2, eigenvectors psi -> phi = M^-1/2 psi
    let mut k = nalgebra::DMatrix::<f64>::zeros(n, n);
    for (i, &ci) in c.iter().enumerate() {
        k[(i, i)] += ci;
        k[(i + 1, i + 1)] += ci;
        k[(i, i + 1)] -= ci;
        k[(i + 1, i)] -= ci;
    }
    for a in 0..n {
        for b in 0..n {
            k[(a, b)] /= (j[a] * j[b]).sqrt();
        }
    }
    let eig = nalgebra::SymmetricEigen::new(k);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let mut out = Vec::new();
    for &m in order.iter().skip(1) {
        let w2 = eig.eigenvalues[m].max(0.0);
        let phi: Vec<f64> = (0..n)
            .map(|i| eig.eigenvectors[(i, m)] / j[i].sqrt())
            .collect();
        let energy: Vec<f64> = (0..n - 1)
            .map(|i| c[i] * (phi[i + 1] - phi[i]).powi(2))
            .collect();
        let total: f64 = energy.iter().sum();
        let (idx, e) = energy
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(i, e)| (i, *e))
            .unwrap_or((0, 0.0));
        out.push(Coupling {
            index: idx + 1,
            stiffness_nm_per_rad: c[idx],
            stiffness_std_nm_per_rad: std.get(idx).copied().unwrap_or(f64::NAN),
            resonance_hz: w2.sqrt() / (2.0 * std::f64::consts::PI),
            strain_energy_share: if total > 0.0 { e / total } else { 0.0 },
        });
    }
    out
}

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
///
/// Serialised honestly: a parameter or frequency whose one-sigma uncertainty is undefined
/// or larger than its value is not identifiable from the data, so its value and its
/// uncertainty are written as `null` and `"identifiable"` (`{"inertia", "stiffness",
/// "damping", "resonance", "antiresonance"}`, one flag per entry) says which; an
/// undefined modal damping ratio is `null` too. No NaN, infinity or relative uncertainty
/// above 100 % is ever written as a number.
#[derive(Debug, Clone)]
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
    /// Their one-sigma uncertainties [Hz], from the fit's covariance (already scaled by
    /// the reduced chi-square where it exceeds 1) by first-order propagation.
    pub resonance_std_hz: Vec<f64>,
    /// Undamped anti-resonances (motor locked) [Hz], ascending.
    pub antiresonance_hz: Vec<f64>,
    /// Their one-sigma uncertainties [Hz], as `resonance_std_hz`.
    pub antiresonance_std_hz: Vec<f64>,
    /// Damping ratio of each mode [-], in the order of `resonance_hz`.
    pub damping_ratio: Vec<f64>,
    /// Total inertia [kg m^2].
    pub total_inertia_kgm2: f64,
    /// Where the compliant couplings are, softest-mode first.
    pub couplings: Vec<Coupling>,
    /// Viscous friction from the motor to the ground [N m s/rad] and its uncertainty, when
    /// the lowest lines showed it significantly (`None`: the chain is free).
    pub ground_damping: Option<crate::identify::ground_damper::GroundDamping>,
}

/// Whether a value with one-sigma uncertainty `std` is identifiable: both defined and the
/// uncertainty not larger than the value.
pub fn identifiable(value: f64, std: f64) -> bool {
    value.is_finite() && std.is_finite() && std <= value.abs()
}

/// `values` and `stds` with the entries that are not [`identifiable`] set to `None`, and
/// the flags.
fn honest(values: &[f64], stds: &[f64]) -> (Vec<Option<f64>>, Vec<Option<f64>>, Vec<bool>) {
    let flags: Vec<bool> = values
        .iter()
        .enumerate()
        .map(|(i, v)| identifiable(*v, stds.get(i).copied().unwrap_or(f64::NAN)))
        .collect();
    let keep = |xs: &[f64]| -> Vec<Option<f64>> {
        xs.iter()
            .zip(&flags)
            .map(|(x, ok)| ok.then_some(*x))
            .collect()
    };
    (keep(values), keep(stds), flags)
}

impl Serialize for ModelSummary {
    fn serialize<S: serde::Serializer>(&self, ser: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let (j, j_sd, j_ok) = honest(&self.inertia_kgm2, &self.inertia_std_kgm2);
        let (c, c_sd, c_ok) = honest(&self.stiffness_nm_per_rad, &self.stiffness_std_nm_per_rad);
        let (d, d_sd, d_ok) = honest(&self.damping_nms_per_rad, &self.damping_std_nms_per_rad);
        let (r, r_sd, r_ok) = honest(&self.resonance_hz, &self.resonance_std_hz);
        let (a, a_sd, a_ok) = honest(&self.antiresonance_hz, &self.antiresonance_std_hz);
        let zeta: Vec<Option<f64>> = self
            .damping_ratio
            .iter()
            .map(|z| z.is_finite().then_some(*z))
            .collect();
        let mut m = ser.serialize_map(Some(17))?;
        m.serialize_entry("masses", &self.masses)?;
        m.serialize_entry("inertia_kgm2", &j)?;
        m.serialize_entry("inertia_std_kgm2", &j_sd)?;
        m.serialize_entry("stiffness_nm_per_rad", &c)?;
        m.serialize_entry("stiffness_std_nm_per_rad", &c_sd)?;
        m.serialize_entry("damping_nms_per_rad", &d)?;
        m.serialize_entry("damping_std_nms_per_rad", &d_sd)?;
        m.serialize_entry("resonance_hz", &r)?;
        m.serialize_entry("resonance_std_hz", &r_sd)?;
        m.serialize_entry("antiresonance_hz", &a)?;
        m.serialize_entry("antiresonance_std_hz", &a_sd)?;
        m.serialize_entry("damping_ratio", &zeta)?;
        m.serialize_entry("total_inertia_kgm2", &self.total_inertia_kgm2)?;
        m.serialize_entry("couplings", &self.couplings)?;
        // 0 when none was seen: the chain is free (the model's parameter is zero)
        let b = self
            .ground_damping
            .map(|g| (g.b_nms_per_rad, g.std_nms_per_rad));
        m.serialize_entry("motor_viscous_nms_per_rad", &b.map_or(0.0, |b| b.0))?;
        m.serialize_entry("motor_viscous_std_nms_per_rad", &b.map(|b| b.1))?;
        m.serialize_entry(
            "identifiable",
            &serde_json::json!({
                "inertia": j_ok,
                "stiffness": c_ok,
                "damping": d_ok,
                "resonance": r_ok,
                "antiresonance": a_ok,
            }),
        )?;
        m.end()
    }
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
        let (antiresonance_std_hz, resonance_std_hz) = spectra_std(fit);
        ModelSummary {
            masses: ch.masses(),
            inertia_kgm2: ch.inertia_kgm2.clone(),
            inertia_std_kgm2: fit.std.inertia_kgm2.clone(),
            stiffness_nm_per_rad: ch.stiffness_nm_per_rad.clone(),
            stiffness_std_nm_per_rad: fit.std.stiffness_nm_per_rad.clone(),
            damping_nms_per_rad: ch.damping_nms_per_rad.clone(),
            damping_std_nms_per_rad: fit.std.damping_nms_per_rad.clone(),
            antiresonance_hz: ch.antiresonances_hz(),
            antiresonance_std_hz,
            resonance_hz,
            resonance_std_hz,
            damping_ratio,
            total_inertia_kgm2: ch.total_inertia(),
            ground_damping: None,
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

/// One-sigma uncertainties of the chain's anti-resonances and resonances [Hz]: the
/// gradient of each frequency in the fit's log-parameters (forward differences of
/// `h = 1e-6`) through the fit's covariance, `sqrt(g^T C g)`. NaN where the covariance is
/// missing or a perturbed chain loses a frequency.
fn spectra_std(fit: &ChainFit) -> (Vec<f64>, Vec<f64>) {
    let ch = &fit.chain;
    let (ar0, r0) = (ch.antiresonances_hz(), ch.resonances_hz());
    let theta: Vec<f64> = ch
        .inertia_kgm2
        .iter()
        .chain(&ch.stiffness_nm_per_rad)
        .chain(&ch.damping_nms_per_rad)
        .map(|v| v.ln())
        .collect();
    let np = theta.len();
    let nan = |v: &[f64]| vec![f64::NAN; v.len()];
    if fit.cov_log.len() != np * np {
        return (nan(&ar0), nan(&r0));
    }
    let n = ch.masses();
    let h = 1e-6;
    // gradients: one column per parameter, for the anti-resonances then the resonances
    let mut grad: Vec<Vec<f64>> = Vec::with_capacity(np);
    for j in 0..np {
        let mut t = theta.clone();
        t[j] += h;
        let c = Chain {
            inertia_kgm2: t[..n].iter().map(|v| v.exp()).collect(),
            stiffness_nm_per_rad: t[n..2 * n - 1].iter().map(|v| v.exp()).collect(),
            damping_nms_per_rad: t[2 * n - 1..].iter().map(|v| v.exp()).collect(),
        };
        let (ar, r) = (c.antiresonances_hz(), c.resonances_hz());
        if ar.len() != ar0.len() || r.len() != r0.len() {
            return (nan(&ar0), nan(&r0));
        }
        grad.push(
            ar.iter()
                .zip(&ar0)
                .chain(r.iter().zip(&r0))
                .map(|(a, b)| (a - b) / h)
                .collect(),
        );
    }
    let m = ar0.len() + r0.len();
    let std: Vec<f64> = (0..m)
        .map(|k| {
            let mut v = 0.0;
            for a in 0..np {
                for b in 0..np {
                    v += grad[a][k] * fit.cov_log[a * np + b] * grad[b][k];
                }
            }
            if v >= 0.0 {
                v.sqrt()
            } else {
                f64::NAN
            }
        })
        .collect();
    (std[..ar0.len()].to_vec(), std[ar0.len()..].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::fit::ChainStd;

    #[test]
    fn parameters_the_data_do_not_identify_are_null_with_a_flag() {
        let m = ModelSummary {
            masses: 2,
            inertia_kgm2: vec![1e-3, 2e-3],
            inertia_std_kgm2: vec![1e-5, 5e-3],
            stiffness_nm_per_rad: vec![400.0],
            stiffness_std_nm_per_rad: vec![f64::NAN],
            damping_nms_per_rad: vec![0.02],
            damping_std_nms_per_rad: vec![f64::INFINITY],
            resonance_hz: vec![110.0],
            resonance_std_hz: vec![0.4],
            antiresonance_hz: vec![70.0],
            antiresonance_std_hz: vec![0.3],
            damping_ratio: vec![f64::NAN],
            total_inertia_kgm2: 3e-3,
            ground_damping: None,
            couplings: Vec::new(),
        };
        let v = serde_json::to_value(&m).unwrap();
        assert_eq!(v["inertia_kgm2"], serde_json::json!([1e-3, null]));
        assert_eq!(v["inertia_std_kgm2"], serde_json::json!([1e-5, null]));
        assert_eq!(v["stiffness_nm_per_rad"], serde_json::json!([null]));
        assert_eq!(v["damping_std_nms_per_rad"], serde_json::json!([null]));
        assert_eq!(v["resonance_hz"], serde_json::json!([110.0]));
        assert_eq!(v["damping_ratio"], serde_json::json!([null]));
        assert_eq!(
            v["identifiable"],
            serde_json::json!({"inertia": [true, false], "stiffness": [false],
                "damping": [false], "resonance": [true], "antiresonance": [true]})
        );
        let text = serde_json::to_string(&v).unwrap().to_lowercase();
        let words: Vec<&str> = text
            .split(|c: char| ",:[]{}\"".contains(c))
            .filter(|w| !w.is_empty())
            .collect();
        assert!(
            !words.iter().any(|w| ["nan", "inf", "infinity"].contains(w)),
            "{text}"
        );
    }

    /// Against the closed form of a two-body chain: `f_AR = sqrt(c / J2) / 2 pi`, so
    /// `d f_AR / d ln c = f_AR / 2`, `d f_AR / d ln J2 = -f_AR / 2`; with independent
    /// log-parameters of variances `vc`, `vj2`, `sigma = f_AR / 2 sqrt(vc + vj2)`.
    #[test]
    fn spectra_uncertainty_matches_the_two_body_closed_form() {
        let chain = Chain::new(vec![1e-3, 3e-3], vec![500.0], vec![0.05]).unwrap();
        // log-parameter variances: J1, J2, c, d
        let var = [4e-4, 9e-4, 1e-4, 2.5e-3];
        let mut cov = vec![0.0; 16];
        for (i, v) in var.iter().enumerate() {
            cov[i * 4 + i] = *v;
        }
        let fit = ChainFit {
            chain: chain.clone(),
            std: ChainStd {
                inertia_kgm2: vec![0.0; 2],
                stiffness_nm_per_rad: vec![0.0],
                damping_nms_per_rad: vec![0.0],
            },
            cov_log: cov,
            cost: 1.0,
            chi2_per_dof: 1.0,
            params: 4,
            lines_used: 100,
            starts: 1,
            starts_converged: 1,
            iterations: 1,
            evaluations_total: 1,
            residual_rms_db: 0.0,
            residual_rms_deg: 0.0,
        };
        let (ar_std, r_std) = spectra_std(&fit);
        let f_ar = (500.0f64 / 3e-3).sqrt() / (2.0 * std::f64::consts::PI);
        let want = f_ar / 2.0 * (var[2] + var[1]).sqrt();
        assert!(
            (ar_std[0] / want - 1.0).abs() < 1e-4,
            "{} vs {want}",
            ar_std[0]
        );
        // resonance: f_R = sqrt(c (1/J1 + 1/J2)) / 2 pi; d ln f_R / d ln c = 1/2,
        // d ln f_R / d ln J1 = -(1/J1) / (2 (1/J1 + 1/J2)), likewise J2
        let (j1, j2): (f64, f64) = (1e-3, 3e-3);
        let f_r = (500.0 * (1.0 / j1 + 1.0 / j2)).sqrt() / (2.0 * std::f64::consts::PI);
        let s = 1.0 / j1 + 1.0 / j2;
        let g = [-(1.0 / j1) / (2.0 * s), -(1.0 / j2) / (2.0 * s), 0.5];
        let want_r =
            f_r * (g[0] * g[0] * var[0] + g[1] * g[1] * var[1] + g[2] * g[2] * var[2]).sqrt();
        assert!(
            (r_std[0] / want_r - 1.0).abs() < 1e-4,
            "{} vs {want_r}",
            r_std[0]
        );
    }
}

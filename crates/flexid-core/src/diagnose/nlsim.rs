//! The diagnosis's own time-domain simulation of the chain with an amplitude-dependent
//! effect, on the recorded excitation: the linear chain discretised exactly (ZOH) on
//! `substeps` sub-steps per sample, the effect's torque held over each sub-step
//! (explicit for the spring nonlinearities; semi-implicit for friction: over each sub-step
//! the Coulomb torque, bounded by `Tc`, is the one that stops the motor if it can, so
//! stiction needs no velocity scale). Deliberately not [`crate::plant::PlantSim`] (RK4 of
//! the full nonlinear equations), which generates the benchmark's data.

use super::lti::{zoh, LinExt};
use crate::analysis::estimate_motion;
use crate::recording::{MotionSignal, Recording};
use num_complex::Complex64;

/// The amplitude-dependent effect simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Nl {
    None,
    /// Coulomb friction `tc` [N m] on the motor (viscous part in [`LinExt::motor_b`]).
    Friction {
        tc: f64,
    },
    /// Dead zone of half-width `g` [rad] in coupling `k` (0-based).
    Backlash {
        k: usize,
        g: f64,
    },
    /// Spring torque `c x (1 + (x/xref)²)` in coupling `k`.
    Hardening {
        k: usize,
        xref: f64,
    },
    /// A cubic spring from the load (the last body) to the ground, torque `-k3 q³`
    /// [`k3` in N m/rad³] (a Duffing oscillator; the Silverbox). The load's absolute
    /// position matters, so a free chain starts moving as in its periodic steady state
    /// (centred, no drift: [`centred_start`]).
    GroundCubic {
        k3: f64,
    },
}

/// Finer steps per sub-step around a backlash contact change.
const MICRO: usize = 8;

/// One exact ZOH step of a linear mode: `x' = A x + bu u + bc fc`, `A` stored column by
/// column so that the step is vector updates over the rows. Each row sums its terms as a
/// tree, not left to right: the products of neighbouring columns in pairs, the pairs
/// added pairwise level by level ([`tree_sum`]), the inputs `bu u + bc fc` last. A
/// sub-step waits on the one before, so the depth of that sum is the simulation's speed:
/// three additions deep for 6 states instead of seven. Every size sums in the same order
/// ([`Prop::apply_rows`], the reference), so the fixed sizes equal it to the bit.
struct Prop {
    /// `A` column-major: `a[c * ns + r] = A[r][c]`.
    a: Vec<f64>,
    bu: Vec<f64>,
    bc: Vec<f64>,
}

/// Most column pairs of a fixed-size step (8 states).
const MAX_PAIRS: usize = 4;

/// `t[0] + t[1] + ...` added pairwise, level by level (an odd last term carried up): the
/// order of every row of [`Prop`]'s step. Streamed as a binary counter (a partial sum per
/// level, merged when two of a level meet, the rest folded from the right at the end),
/// which adds in that order (`the_tree_sum_adds_pairs_level_by_level`) with no buffer: a
/// sub-step allocates nothing for any number of states.
#[inline(always)]
fn tree_sum(terms: impl Iterator<Item = f64>) -> f64 {
    // partial sums and their levels; 64 levels hold 2^64 terms
    let mut sum = [0.0f64; 64];
    let mut level = [0u32; 64];
    let mut top = 0;
    for t in terms {
        let (mut v, mut l) = (t, 0);
        while top > 0 && level[top - 1] == l {
            v = sum[top - 1] + v;
            top -= 1;
            l += 1;
        }
        sum[top] = v;
        level[top] = l;
        top += 1;
    }
    if top == 0 {
        return 0.0;
    }
    let mut s = sum[top - 1];
    for i in (0..top - 1).rev() {
        s = sum[i] + s;
    }
    s
}

impl Prop {
    fn new(ad: &nalgebra::DMatrix<f64>, bu: Vec<f64>, bc: Vec<f64>) -> Self {
        let ns = ad.nrows();
        Prop {
            a: (0..ns * ns).map(|i| ad[(i % ns, i / ns)]).collect(),
            bu,
            bc,
        }
    }

    /// The step with `N` states known at compile time (`N = 0`: any size).
    #[inline(always)]
    fn apply<const N: usize>(&self, x: &[f64], xn: &mut [f64], u: f64, fc: f64) {
        if N == 0 || N % 2 == 1 || N > 2 * MAX_PAIRS {
            self.apply_rows(x, xn, u, fc)
        } else {
            self.apply_fixed::<N>(x, xn, u, fc)
        }
    }

    /// [`Prop::apply_rows`] for an even `N <= 8`, the rows as vectors: the pairs'
    /// products, then their tree, as whole columns.
    #[inline(always)]
    fn apply_fixed<const N: usize>(&self, x: &[f64], xn: &mut [f64], u: f64, fc: f64) {
        let x: &[f64; N] = x.try_into().expect("state size");
        let bu: &[f64; N] = self.bu[..].try_into().expect("state size");
        let bc: &[f64; N] = self.bc[..].try_into().expect("state size");
        let a: &[f64] = &self.a[..N * N];
        let mut p = [[0.0; N]; MAX_PAIRS];
        let pairs = N / 2;
        for (j, pj) in p.iter_mut().enumerate().take(pairs) {
            let c0: &[f64; N] = a[2 * j * N..(2 * j + 1) * N].try_into().expect("column");
            let c1: &[f64; N] = a[(2 * j + 1) * N..(2 * j + 2) * N]
                .try_into()
                .expect("column");
            let (x0, x1) = (x[2 * j], x[2 * j + 1]);
            for r in 0..N {
                pj[r] = c0[r] * x0 + c1[r] * x1;
            }
        }
        // the tree of [`tree_sum`] over 2, 3 or 4 pairs, column-wise
        let s: [f64; N] = match pairs {
            2 => std::array::from_fn(|r| p[0][r] + p[1][r]),
            3 => std::array::from_fn(|r| (p[0][r] + p[1][r]) + p[2][r]),
            _ => std::array::from_fn(|r| (p[0][r] + p[1][r]) + (p[2][r] + p[3][r])),
        };
        for r in 0..N {
            xn[r] = s[r] + (bu[r] * u + bc[r] * fc);
        }
    }

    /// The plain row-by-row product (any size; the reference of [`Prop::apply_fixed`]):
    /// each row the [`tree_sum`] of its column pairs' products (an odd last column alone),
    /// plus the inputs.
    fn apply_rows(&self, x: &[f64], xn: &mut [f64], u: f64, fc: f64) {
        let ns = x.len();
        for (r, out) in xn.iter_mut().enumerate() {
            let pairs = (0..ns).step_by(2).map(|c| {
                if c + 1 < ns {
                    self.a[c * ns + r] * x[c] + self.a[(c + 1) * ns + r] * x[c + 1]
                } else {
                    self.a[c * ns + r] * x[c]
                }
            });
            *out = tree_sum(pairs) + (self.bu[r] * u + self.bc[r] * fc);
        }
    }
}

/// Simulated motor position and velocity at the sample instants, and the RMS deflection
/// of each coupling.
#[derive(Debug, Clone, Default)]
pub struct SimOut {
    /// Motor position [rad] per sample (empty when not recorded: [`Record`]).
    pub pos: Vec<f64>,
    /// Motor velocity [rad/s] per sample (empty when not recorded: [`Record`]).
    pub vel: Vec<f64>,
    /// RMS deflection of each coupling [rad].
    pub defl_rms: Vec<f64>,
}

/// Which of the motor's motions a simulation records at the sample instants (the search
/// estimates one of them: the other would be written for nothing, 8 bytes a sample).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Record {
    Both,
    Position,
    Velocity,
}

impl Record {
    /// The motion [`sim_frf`] estimates for `rec` (both when the recording has none).
    pub fn for_estimate(rec: &Recording) -> Record {
        match rec.preferred_motion().map(|m| m.0) {
            Some(MotionSignal::Position) => Record::Position,
            Some(MotionSignal::Velocity) => Record::Velocity,
            _ => Record::Both,
        }
    }

    fn position(self) -> bool {
        self != Record::Velocity
    }

    fn velocity(self) -> bool {
        self != Record::Position
    }
}

/// The chain `lin` with the effect `nl` under the torque command `u` [N m] at `fs` [Hz],
/// `substeps` sub-steps per sample, from rest (a free chain under a ground cubic: from its
/// centred start).
pub fn simulate(lin: &LinExt, nl: Nl, u: &[f64], fs: f64, substeps: usize) -> SimOut {
    simulate_lanes(lin, nl, &[u], fs, substeps)
        .pop()
        .expect("one lane")
}

/// [`simulate`] of the same chain and effect under several excitations `us` (the levels of
/// a measurement), one [`SimOut`] each, equal to the bit to [`simulate`] of each alone. The
/// excitations are stepped together, sub-step by sub-step: one simulation's sub-step waits
/// on its previous one (a chain of dependent multiplications and additions), so the
/// processor works on the others' in that time.
pub fn simulate_lanes(
    lin: &LinExt,
    nl: Nl,
    us: &[&[f64]],
    fs: f64,
    substeps: usize,
) -> Vec<SimOut> {
    let mut outs = Vec::new();
    simulate_lanes_into(lin, nl, us, fs, substeps, Record::Both, &mut outs);
    outs
}

/// [`simulate_lanes`] recording `record` only, into `outs` (one [`SimOut`] per excitation
/// afterwards): the vectors `outs` holds on entry are written again, so a caller that
/// keeps them simulates without allocating (a fresh buffer of 10⁵ samples and more is
/// fresh memory, a page fault every 512 samples). Equal to the bit to [`simulate_lanes`]
/// in what is recorded.
pub fn simulate_lanes_into(
    lin: &LinExt,
    nl: Nl,
    us: &[&[f64]],
    fs: f64,
    substeps: usize,
    record: Record,
    outs: &mut Vec<SimOut>,
) {
    outs.resize_with(us.len(), SimOut::default);
    let s = setup(lin, nl, fs, substeps);
    let starts: Vec<Vec<f64>> = us
        .iter()
        .map(|u| match nl {
            Nl::GroundCubic { .. } if lin.ground_b == 0.0 && lin.ground_k == 0.0 => {
                centred_start(&lin.chain, lin.motor_b, u, fs)
            }
            _ => vec![0.0; s.bm.len()],
        })
        .collect();
    let job = Job {
        s: &s,
        nl,
        us,
        starts: &starts,
        record,
    };
    integrate_on(wide(), &job, outs)
}

/// What the time loop simulates: the propagators, the effect, the excitations with their
/// initial states, and what it records.
struct Job<'a> {
    s: &'a Setup,
    nl: Nl,
    us: &'a [&'a [f64]],
    starts: &'a [Vec<f64>],
    record: Record,
}

/// Whether the processor runs [`integrate_wide`] (AVX2).
fn wide() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The time loop, compiled for AVX2 when `wide` and the processor has it.
fn integrate_on(wide: bool, job: &Job, outs: &mut Vec<SimOut>) {
    #[cfg(target_arch = "x86_64")]
    if wide && std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2 (checked just above)
        unsafe { integrate_wide(job, outs) };
        return;
    }
    let _ = wide;
    integrate_sized(job, outs)
}

/// [`integrate_sized`] compiled for AVX2: the state's rows four at a time instead of two
/// (the baseline x86-64 has SSE2 only); 0.9-1.1x per sub-step by `probe_sub_step_time`
/// against the plain loop inlined alike, about 6 % of A 50402's CPU time against the
/// loop before (not inlined).
/// The same operations in the same order (Rust never fuses a multiplication and an
/// addition on its own), so every result is equal to the bit
/// (`wide_integration_equals_the_plain_one`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn integrate_wide(job: &Job, outs: &mut Vec<SimOut>) {
    integrate_sized(job, outs)
}

/// The time loop for the setup's number of states: fixed sizes (the chain's 2n states)
/// unroll and vectorise. Inlined, with what it calls, into [`integrate_wide`]'s AVX2 code.
#[inline(always)]
fn integrate_sized(job: &Job, outs: &mut Vec<SimOut>) {
    match job.s.bm.len() {
        4 => integrate_with::<4, [f64; 4]>(job, outs),
        6 => integrate_with::<6, [f64; 6]>(job, outs),
        8 => integrate_with::<8, [f64; 8]>(job, outs),
        _ => integrate_with::<0, Vec<f64>>(job, outs),
    }
}

/// The propagators of [`simulate`] for `lin` and `nl` at `substeps` sub-steps per sample.
fn setup(lin: &LinExt, nl: Nl, fs: f64, substeps: usize) -> Setup {
    let ch = &lin.chain;
    let n = ch.masses();
    let k = match nl {
        Nl::Backlash { k, .. } | Nl::Hardening { k, .. } => k.min(n.saturating_sub(2)),
        _ => 0,
    };
    let mut plain = lin.clone();
    plain.current_loop = None;
    let (a, mut b) = plain.continuous(if n > 1 { Some(k) } else { None });
    if let Nl::GroundCubic { .. } = nl {
        // the ground spring's torque acts on the load alone: input column 2
        b = b.resize_horizontally(3, 0.0);
        b.column_mut(2).fill(0.0);
        b[(2 * n - 1, 2)] = 1.0 / ch.inertia_kgm2[n - 1];
    }
    let sub = substeps.max(1);
    let dt = 1.0 / fs / sub as f64;
    let ns = a.nrows();
    let col = |bd: &nalgebra::DMatrix<f64>, j: usize| -> Vec<f64> {
        if j < bd.ncols() {
            (0..ns).map(|r| bd[(r, j)]).collect()
        } else {
            vec![0.0; ns]
        }
    };
    let prop = |a: &nalgebra::DMatrix<f64>, b: &nalgebra::DMatrix<f64>, t: f64| {
        let (ad, bd) = zoh(a, b, t);
        Prop::new(&ad, col(&bd, 0), col(&bd, 2))
    };
    let (_, bd) = zoh(&a, &b, dt);
    let bm = if n > 1 { col(&bd, 1) } else { col(&bd, 0) };
    let lin_p = prop(&a, &b, dt);
    // backlash is piecewise linear: in contact the chain with a constant offset torque
    // `-c g sign(x)` (exact under the hold), inside the gap the chain with that coupling
    // removed (its own exact propagator). A sub-step whose end lies in another mode than
    // its start is redone on MICRO finer steps, so the switching instant is resolved to
    // 1/(substeps·MICRO) of a sample.
    let modes = match nl {
        Nl::Backlash { .. } if n > 1 => {
            let mut open = plain.clone();
            open.chain.stiffness_nm_per_rad[k] = 0.0;
            open.chain.damping_nms_per_rad[k] = 0.0;
            let (af, bf) = open.continuous(Some(k));
            let dm = dt / MICRO as f64;
            Some([prop(&af, &bf, dt), prop(&a, &b, dm), prop(&af, &bf, dm)])
        }
        _ => None,
    };
    let c = if n > 1 {
        ch.stiffness_nm_per_rad[k]
    } else {
        0.0
    };
    // the effect's constants, so that a sub-step multiplies only (a division waits on its
    // operands some four times longer, and a sub-step waits on the one before)
    let cubic = match nl {
        Nl::Hardening { xref, .. } if n > 1 => c / (xref * xref),
        Nl::GroundCubic { k3 } => -k3,
        _ => 0.0,
    };
    let hermite = match nl {
        Nl::Hardening { .. } if n > 1 => Some(Hermite::new(&a, &b, dt)),
        Nl::GroundCubic { .. } => Some(Hermite::new(&a, &b, dt)),
        _ => None,
    };
    let inv_bm = if n > 0 && bm[n] != 0.0 {
        1.0 / bm[n]
    } else {
        0.0
    };
    Setup {
        n,
        k,
        c,
        cubic,
        inv_bm,
        sub,
        lin_p,
        modes,
        hermite,
        bm,
    }
}

/// What [`simulate`] integrates with: the propagators and the effect's coupling.
struct Setup {
    n: usize,
    k: usize,
    c: f64,
    /// The cubic's coefficient: `c / xref²` of a hardening coupling [N m/rad³], `-k3` of a
    /// ground cubic.
    cubic: f64,
    /// `1 / bm[n]`: the motor velocity one unit of torque adds over a sub-step, inverted
    /// (0 when it adds none).
    inv_bm: f64,
    sub: usize,
    lin_p: Prop,
    /// Backlash: free flight over a sub-step, contact and free flight over a micro-step.
    modes: Option<[Prop; 3]>,
    /// A cubic spring: the input columns of its torque's polynomial over a sub-step.
    hermite: Option<Hermite>,
    /// Input column of a motor torque over a sub-step.
    bm: Vec<f64>,
}

/// The response over one sub-step of length `h` to a torque on the spring's input column
/// that varies as `(s/h)^j` (`0 <= s <= h`), `m[j] = ∫₀ʰ e^{A(h-s)} b (s/h)^j ds`, `j = 1..3`
/// (`j = 0` is the held column of [`Prop`]): the columns of a cubic spring's torque
/// integrated as a cubic polynomial in time over the sub-step instead of held.
///
/// The step is a predictor-corrector on the spring's torque `f` and its rate `ḟ`, both
/// exact functions of the state (`f = κ d³`, `ḟ = 3 κ d² ḋ` of the deflection `d`): the
/// predictor takes `f` as its first-order Taylor polynomial from the sub-step's start, the
/// corrector as the cubic Hermite polynomial through `f`, `ḟ` at both ends (the end's from
/// the predicted state). The linear chain stays exact (ZOH); the torque's error is the
/// Hermite interpolant's, fourth order in `h` (`cubic_springs_converge_at_fourth_order`).
/// The held torque extrapolated to the sub-step's middle it replaces was second order:
/// on the 2 sub-steps of a 4 kHz sample, a strongly stiffening coupling (exploration
/// A 920300, a 2-mass sweep some 5 `x_ref` deep at the resonance) left the bounds at the
/// true model, which now has a chi² of 1.06e5 (692 converged, on 8 sub-steps and more;
/// the fitted nominal chain 5.9e5), and the diagnosis names it (`x_ref` 7.14e-4 rad
/// against 6.81e-4; `unexplained` before). Dividing the sub-step where the spring
/// stiffens beyond the chain's fastest mode brought that chi² to 2.3e3 but did not
/// change the verdict, and cost up to 16 steps a sub-step wherever the search tried a
/// stiff spring (a 2-mass stepped sine took 2.5 times as long): not kept.
#[derive(Debug, Clone)]
struct Hermite {
    /// Sub-step [s].
    h: f64,
    /// The columns of `(s/h)`, `(s/h)²`, `(s/h)³` (`m[j]` above for `j` = 1, 2, 3).
    m: [Vec<f64>; 3],
}

impl Hermite {
    /// The columns of `A`, `b`'s column 2 (the spring's torque) over `h`, from the matrix
    /// exponential of `A` augmented by a chain of three integrators.
    fn new(a: &nalgebra::DMatrix<f64>, b: &nalgebra::DMatrix<f64>, h: f64) -> Self {
        let ns = a.nrows();
        let mut aug = nalgebra::DMatrix::<f64>::zeros(ns + 4, ns + 4);
        aug.view_mut((0, 0), (ns, ns)).copy_from(&(a * h));
        if b.ncols() > 2 {
            for r in 0..ns {
                aug[(r, ns)] = b[(r, 2)] * h;
            }
        }
        for j in 0..3 {
            aug[(ns + j, ns + j + 1)] = 1.0;
        }
        let norm = aug.amax();
        let e = if norm.is_finite() && norm <= super::lti::ZOH_MAX_NORM {
            aug.exp()
        } else {
            nalgebra::DMatrix::from_element(ns + 4, ns + 4, f64::NAN)
        };
        // with the integrators on the normalised time σ = s/h, the column of the input
        // started at σ^j/j! is ∫ e^{A(h-s)} b σ^j/j! ds
        let col =
            |j: usize, fact: f64| -> Vec<f64> { (0..ns).map(|r| fact * e[(r, ns + j)]).collect() };
        Hermite {
            h,
            m: [col(1, 1.0), col(2, 2.0), col(3, 6.0)],
        }
    }
}

/// The initial state of a chain free of springs to the ground that moves as in its
/// periodic steady state under `u`: every body at the rigid body's velocity offset and
/// position offset that make the rigid motion's mean velocity and mean position zero over
/// the record (from rest, a zero-mean torque leaves the rigid body a constant velocity
/// that depends on the excitation's start, or, with viscous friction `motor_b` [N m s/rad]
/// to the ground, a position offset: a drift or an offset that a spring to the ground
/// would see and the measured axis, long centred by its spring or its position loop, does
/// not have). With `motor_b` the velocity offset `v0` decays as `e^{-b t/J}`, and `v0` is
/// chosen so that the mean velocity is zero with its decay (exploration A 920402, a cubic
/// ground spring on a 3-mass chain with viscous friction, started from rest: the true
/// model's chi² 49 329, against 1319 for the chain without the spring; started centred,
/// 646; 634 from the world's own start, which takes the free body's offsets and lets the
/// damper act on them). The state holds `2n` entries (positions, velocities), zero beyond.
pub fn centred_start(ch: &crate::model::Chain, motor_b: f64, u: &[f64], fs: f64) -> Vec<f64> {
    let n = ch.masses();
    let mut x = vec![0.0; 2 * n];
    if u.is_empty() {
        return x;
    }
    let (jt, dt) = (ch.total_inertia(), 1.0 / fs);
    let b = if motor_b.is_finite() {
        motor_b.max(0.0)
    } else {
        0.0
    };
    // rigid velocity and position from rest under the held torque
    let (mut w, mut r) = (0.0, 0.0);
    let (mut w_sum, mut r_sum) = (0.0, 0.0);
    for &uk in u {
        w_sum += w;
        r_sum += r;
        let a = (uk - b * w) / jt;
        r += w * dt + 0.5 * a * dt * dt;
        w += a * dt;
    }
    let len = u.len() as f64;
    let (v0, p0) = if b == 0.0 {
        let v0 = -w_sum / len;
        // positions shift by v0 t as well: mean of t over the samples is (len - 1) dt / 2
        (v0, -(r_sum / len + v0 * (len - 1.0) * dt / 2.0))
    } else {
        // the offset's velocity g(t) = e^{-t/τ} and position G(t) = τ (1 - g(t)), their
        // means over the samples
        let tau = jt / b;
        let q = (-dt / tau).exp();
        let g_mean = if q < 1.0 {
            (1.0 - q.powf(len)) / (1.0 - q) / len
        } else {
            1.0
        };
        let big_g_mean = tau * (1.0 - g_mean);
        let v0 = -(w_sum / len) / g_mean;
        (v0, -(r_sum / len + v0 * big_g_mean))
    };
    for i in 0..n {
        x[i] = p0;
        x[n + i] = v0;
    }
    x
}

/// The torque of a cubic spring nonlinearity beyond the linear chain, on its input column,
/// and its rate [N m/s] (of the state's velocities): the hardening coupling's `c x
/// (x/x_ref)²` on coupling `k`'s deflection, the ground spring's `-k3 q³` on the load's
/// position; `None` for the other effects. The torque over a sub-step is [`Hermite`]'s.
#[inline(always)]
fn cubic_correction(nl: Nl, x: &[f64], n: usize, k: usize, cubic: f64) -> Option<(f64, f64)> {
    let (d, v) = match nl {
        Nl::Hardening { .. } if n > 1 => (x[k + 1] - x[k], x[n + k + 1] - x[n + k]),
        Nl::GroundCubic { .. } => (x[n - 1], x[2 * n - 1]),
        _ => return None,
    };
    let d2 = d * d;
    Some((cubic * d2 * d, 3.0 * cubic * d2 * v))
}

/// `x += m a` over the state (`N` known at compile time, `N = 0`: any size).
#[inline(always)]
fn axpy<const N: usize>(x: &mut [f64], m: &[f64], a: f64) {
    if N > 0 {
        let x: &mut [f64; N] = x.try_into().expect("state size");
        let m: &[f64; N] = m.try_into().expect("state size");
        for r in 0..N {
            x[r] += m[r] * a;
        }
    } else {
        for (x, m) in x.iter_mut().zip(m) {
            *x += m * a;
        }
    }
}

/// `x += (m a + q b)` over the state, the sum in brackets first.
#[inline(always)]
fn axpy2<const N: usize>(x: &mut [f64], m: &[f64], a: f64, q: &[f64], b: f64) {
    if N > 0 {
        let x: &mut [f64; N] = x.try_into().expect("state size");
        let m: &[f64; N] = m.try_into().expect("state size");
        let q: &[f64; N] = q.try_into().expect("state size");
        for r in 0..N {
            x[r] += m[r] * a + q[r] * b;
        }
    } else {
        for ((x, m), q) in x.iter_mut().zip(m).zip(q) {
            *x += m * a + q * b;
        }
    }
}

/// A state vector: on the stack for a size known at compile time (`[f64; N]`, kept in
/// registers), on the heap for any other.
trait StateBuf: AsRef<[f64]> + AsMut<[f64]> {
    fn zeros(ns: usize) -> Self;
}

impl StateBuf for Vec<f64> {
    fn zeros(ns: usize) -> Self {
        vec![0.0; ns]
    }
}

impl<const N: usize> StateBuf for [f64; N] {
    fn zeros(_: usize) -> Self {
        [0.0; N]
    }
}

/// One simulation of [`simulate_lanes`]: its state and what it has recorded.
struct Lane<'a, B> {
    u: &'a [f64],
    x: B,
    xn: B,
    xt: B,
    record: Record,
    pos: Vec<f64>,
    vel: Vec<f64>,
    dsum: Vec<f64>,
    /// The state left every bound (a spring stiffened beyond the step): no model.
    unstable: bool,
}

impl<'a, B: StateBuf> Lane<'a, B> {
    /// A lane from `start`, recording `record` into the buffers of `spare` (emptied).
    fn new(
        u: &'a [f64],
        start: &[f64],
        ns: usize,
        n: usize,
        record: Record,
        spare: SimOut,
    ) -> Self {
        let mut x = B::zeros(ns);
        let m = start.len().min(ns);
        x.as_mut()[..m].copy_from_slice(&start[..m]);
        let buffer = |mut v: Vec<f64>, wanted: bool| {
            v.clear();
            if wanted {
                v.reserve(u.len());
            }
            v
        };
        let mut dsum = spare.defl_rms;
        dsum.clear();
        dsum.resize(n.saturating_sub(1), 0.0);
        Lane {
            u,
            x,
            xn: B::zeros(ns),
            xt: B::zeros(ns),
            record,
            pos: buffer(spare.pos, record.position()),
            vel: buffer(spare.vel, record.velocity()),
            dsum,
            unstable: false,
        }
    }

    /// Sample `i`: record the state at the sample instant, step it over the sample, check
    /// it.
    #[inline(always)]
    fn sample<const N: usize>(&mut self, s: &Setup, nl: Nl, i: usize) {
        self.record(s.n);
        let uk = self.u[i];
        for _ in 0..s.sub {
            self.sub_step::<N>(s, nl, uk);
        }
        self.check();
    }

    /// Record the state at the sample instant.
    #[inline(always)]
    fn record(&mut self, n: usize) {
        let x = self.x.as_ref();
        if self.record.position() {
            self.pos.push(x[0]);
        }
        if self.record.velocity() {
            self.vel.push(x[n]);
        }
        for (i, s) in self.dsum.iter_mut().enumerate() {
            let dx = x[i + 1] - x[i];
            *s += dx * dx;
        }
    }

    /// One sub-step under the held torque `uk` [N m].
    #[inline(always)]
    fn sub_step<const N: usize>(&mut self, s: &Setup, nl: Nl, uk: f64) {
        let Setup {
            n,
            k,
            c,
            ref lin_p,
            ref modes,
            ref bm,
            ..
        } = *s;
        let ns = bm.len();
        match (nl, modes) {
            (Nl::Backlash { g, .. }, Some([free, lin_m, free_m])) => {
                let side = |x: &[f64]| {
                    let dx = x[k + 1] - x[k];
                    if dx.abs() < g {
                        0.0
                    } else {
                        dx.signum()
                    }
                };
                let s0 = side(self.x.as_ref());
                let p = if s0 == 0.0 { free } else { lin_p };
                p.apply::<N>(self.x.as_ref(), self.xn.as_mut(), uk, -c * g * s0);
                if side(self.xn.as_ref()) != s0 {
                    self.xt.as_mut().copy_from_slice(self.x.as_ref());
                    for _ in 0..MICRO {
                        let sj = side(self.xt.as_ref());
                        let p = if sj == 0.0 { free_m } else { lin_m };
                        p.apply::<N>(self.xt.as_ref(), self.xn.as_mut(), uk, -c * g * sj);
                        std::mem::swap(&mut self.xt, &mut self.xn);
                    }
                    std::mem::swap(&mut self.xt, &mut self.xn);
                }
            }
            _ => match &s.hermite {
                Some(he) => self.hermite_step::<N>(lin_p, he, s, nl, uk),
                None => lin_p.apply::<N>(self.x.as_ref(), self.xn.as_mut(), uk, 0.0),
            },
        }
        if let Nl::Friction { tc } = nl {
            if s.inv_bm != 0.0 {
                let xn = self.xn.as_mut();
                let tf = (-xn[n] * s.inv_bm).clamp(-tc, tc);
                for r in 0..ns {
                    xn[r] += bm[r] * tf;
                }
            }
        }
        std::mem::swap(&mut self.x, &mut self.xn);
    }

    /// One step of a cubic spring from `x` into `xn` on `p` and `he` ([`Hermite`]): the
    /// predictor takes the torque's first-order Taylor polynomial, the corrector the cubic
    /// Hermite polynomial through both ends.
    #[inline(always)]
    fn hermite_step<const N: usize>(&mut self, p: &Prop, he: &Hermite, s: &Setup, nl: Nl, uk: f64) {
        let (n, k, ns) = (s.n, s.k, s.bm.len());
        let Some((f0, r0)) = cubic_correction(nl, self.x.as_ref(), n, k, s.cubic) else {
            return p.apply::<N>(self.x.as_ref(), self.xn.as_mut(), uk, 0.0);
        };
        let r0h = r0 * he.h;
        p.apply::<N>(self.x.as_ref(), self.xn.as_mut(), uk, f0);
        axpy::<N>(self.xn.as_mut(), &he.m[0][..ns], r0h);
        if let Some((f1, r1)) = cubic_correction(nl, self.xn.as_ref(), n, k, s.cubic) {
            let r1h = r1 * he.h;
            let c2 = 3.0 * (f1 - f0) - (2.0 * r0h + r1h);
            let c3 = 2.0 * (f0 - f1) + (r0h + r1h);
            axpy2::<N>(self.xn.as_mut(), &he.m[1][..ns], c2, &he.m[2][..ns], c3);
        }
    }

    /// Check the state after a sample's sub-steps.
    #[inline(always)]
    fn check(&mut self) {
        if !self
            .x
            .as_ref()
            .iter()
            .all(|v| v.is_finite() && v.abs() < 1e12)
        {
            self.unstable = true;
        }
    }

    /// Samples `from..` alone, until the end or the state leaves the bounds.
    #[inline(always)]
    fn run<const N: usize>(&mut self, s: &Setup, nl: Nl, from: usize) {
        for i in from..self.u.len() {
            if self.unstable {
                break;
            }
            self.sample::<N>(s, nl, i);
        }
    }

    /// The lane's [`SimOut`] in its own buffers (NaN throughout when it left the bounds).
    fn finish(self, n: usize) -> SimOut {
        let (mut pos, mut vel, mut defl_rms) = (self.pos, self.vel, self.dsum);
        if self.unstable {
            let bad = |v: &mut Vec<f64>, wanted: bool, len: usize| {
                v.clear();
                if wanted {
                    v.resize(len, f64::NAN);
                }
            };
            bad(&mut pos, self.record.position(), self.u.len());
            bad(&mut vel, self.record.velocity(), self.u.len());
            bad(&mut defl_rms, true, n.saturating_sub(1));
            return SimOut { pos, vel, defl_rms };
        }
        let len = self.u.len().max(1) as f64;
        for s in defl_rms.iter_mut() {
            *s = (*s / len).sqrt();
        }
        SimOut { pos, vel, defl_rms }
    }
}

/// Two lanes stepped together, sub-step by sub-step, while both have samples and stay in
/// bounds; then each alone to its end.
#[inline(always)]
fn run_pair<const N: usize, B: StateBuf>(a: &mut Lane<B>, b: &mut Lane<B>, s: &Setup, nl: Nl) {
    let common = a.u.len().min(b.u.len());
    let mut done = 0;
    while done < common && !a.unstable && !b.unstable {
        a.record(s.n);
        b.record(s.n);
        let (ua, ub) = (a.u[done], b.u[done]);
        for _ in 0..s.sub {
            a.sub_step::<N>(s, nl, ua);
            b.sub_step::<N>(s, nl, ub);
        }
        a.check();
        b.check();
        done += 1;
    }
    a.run::<N>(s, nl, done);
    b.run::<N>(s, nl, done);
}

/// The time loop of [`simulate_lanes`], `N` states in a `B` (`N = 0`: any number, on the
/// heap): the lanes two by two (see [`run_pair`]), each to its own length; a lane that
/// leaves the bounds stops (its output is NaN).
#[inline(always)]
fn integrate_with<const N: usize, B: StateBuf>(job: &Job, outs: &mut Vec<SimOut>) {
    let Job {
        s,
        nl,
        us,
        starts,
        record,
    } = *job;
    let (n, ns) = (s.n, s.bm.len());
    let mut lanes: Vec<Lane<B>> = us
        .iter()
        .zip(starts)
        .zip(outs.drain(..))
        .map(|((u, start), spare)| Lane::new(u, start, ns, n, record, spare))
        .collect();
    for pair in lanes.chunks_mut(2) {
        match pair {
            [a, b] => run_pair::<N, B>(a, b, s, nl),
            [a] => a.run::<N>(s, nl, 0),
            _ => {}
        }
    }
    outs.extend(lanes.into_iter().map(|l| l.finish(n)));
}

/// A stepped-sine recording cut to each block's settle periods and its first `steady`
/// steady ones (the search's short simulation; a stepped sine's record is long: 40 dwells
/// of 200 000 samples and more, where a multisine needs one period): the blocks' torque
/// back to back (and each recorded column cut alike, so that the simulation's motion
/// goes where the measurement's was), their descriptions moved and shortened to match.
/// `None` when the recording is not a stepped sine with blocks or is not shorter so.
/// The block estimator then gives the same lines in the same order; in the steady state
/// of a noise-free simulation, the same values (the next block starts where the shortened
/// one ends, as it starts where the full one ends: its settle periods absorb either).
pub fn shortened_stepped(rec: &Recording, steady: usize) -> Option<Recording> {
    let info = rec.sidecar.excitation.as_ref()?;
    if info.blocks.is_empty() || steady == 0 {
        return None;
    }
    let total = rec.torque_cmd_nm.len();
    let mut ranges = Vec::with_capacity(info.blocks.len());
    let mut blocks = Vec::with_capacity(info.blocks.len());
    let mut len = 0;
    for b in &info.blocks {
        let keep = steady.min(b.periods);
        let end = (b.start + (b.settle_periods + keep) * b.period_samples).min(total);
        if b.start >= end {
            return None;
        }
        let mut nb = b.clone();
        nb.start = len;
        nb.periods = keep;
        len += end - b.start;
        ranges.push(b.start..end);
        blocks.push(nb);
    }
    if len >= total {
        return None;
    }
    let cut = |x: &[f64]| -> Vec<f64> {
        ranges
            .iter()
            .flat_map(|r| x[r.start.min(x.len())..r.end.min(x.len())].iter().copied())
            .collect()
    };
    let mut sidecar = rec.sidecar.clone();
    if let Some(e) = sidecar.excitation.as_mut() {
        e.blocks = blocks;
    }
    let fs = rec.sample_rate_hz;
    Some(Recording {
        time_s: (0..len).map(|k| k as f64 / fs).collect(),
        torque_cmd_nm: cut(&rec.torque_cmd_nm),
        position_rad: rec.position_rad.as_deref().map(cut),
        velocity_rad_s: rec.velocity_rad_s.as_deref().map(cut),
        acceleration_rad_s2: rec.acceleration_rad_s2.as_deref().map(cut),
        torque_actual_nm: rec.torque_actual_nm.as_deref().map(cut),
        sample_rate_hz: fs,
        sidecar,
    })
}

/// The FRF of the simulated response, estimated exactly as the measurement's (same
/// recording description, same estimator), on the lines `keep` of that estimate. A
/// simulation of the whole of `rec` (a stepped sine's shortened record among them) is
/// estimated against `rec` itself, nothing copied; a shorter one against the recording's
/// description cut to its length. The simulated motion is never searched for an encoder's
/// grid: only `h` is returned, which the grid does not change.
pub fn sim_frf(
    rec: &Recording,
    band: Option<[f64; 2]>,
    keep: &[usize],
    out: &SimOut,
) -> Option<Vec<Complex64>> {
    let n = out.pos.len().min(rec.len());
    let motion = rec.preferred_motion()?.0;
    let signal = match motion {
        MotionSignal::Position => &out.pos[..n],
        MotionSignal::Velocity => &out.vel[..n],
        MotionSignal::Acceleration => return None,
    };
    let e = if n == rec.len() {
        estimate_motion(rec, motion, signal, None, band).ok()?
    } else {
        estimate_motion(&cut_description(rec, n), motion, signal, None, band).ok()?
    };
    keep.iter().map(|&i| e.frf.h.get(i).copied()).collect()
}

/// The recording's description (time, torque command, sidecar) cut to its first `n`
/// samples, no motion columns: for a shortened simulation (the search) of a periodic
/// excitation, its steady periods only.
fn cut_description(rec: &Recording, n: usize) -> Recording {
    let mut r = Recording {
        time_s: rec.time_s[..n.min(rec.time_s.len())].to_vec(),
        torque_cmd_nm: rec.torque_cmd_nm[..n].to_vec(),
        position_rad: None,
        velocity_rad_s: None,
        acceleration_rad_s2: None,
        torque_actual_nm: None,
        sample_rate_hz: rec.sample_rate_hz,
        sidecar: rec.sidecar.clone(),
    };
    if let Some(e) = r.sidecar.excitation.as_mut() {
        if e.period_samples > 0 {
            e.periods = (n / e.period_samples)
                .saturating_sub(e.transient_periods)
                .max(1);
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Chain;
    use crate::plant::{Backlash, Effects, Hardening, PlantSim, PlantSpec};

    /// Motor velocity of the naive reference, the plant's RK4 of the full nonlinear
    /// equations on 40 sub-steps, sampled like [`simulate`]'s (before each step).
    fn reference(spec: &PlantSpec, u: &[f64], fs: f64) -> Vec<f64> {
        let mut sim = PlantSim::new(spec, fs, 40, 1).unwrap();
        u.iter()
            .map(|&t| {
                let v = sim.body_velocities()[0];
                sim.step(t);
                v
            })
            .collect()
    }

    /// The tree sum adds every term once, in the stated order: pairs first, then pairs of
    /// pairs (against the order written out by hand, and the plain sum to rounding).
    #[test]
    fn the_tree_sum_adds_pairs_level_by_level() {
        let t: Vec<f64> = (0..40)
            .map(|i| 1.0 / (1.0 + i as f64).powi(3) + 1e-17 * i as f64)
            .collect();
        let by_hand = [
            t[0],
            t[0] + t[1],
            (t[0] + t[1]) + t[2],
            (t[0] + t[1]) + (t[2] + t[3]),
            ((t[0] + t[1]) + (t[2] + t[3])) + t[4],
        ];
        for (m, want) in by_hand.iter().enumerate() {
            let got = tree_sum(t[..m + 1].iter().copied());
            assert_eq!(got.to_bits(), want.to_bits(), "{} terms", m + 1);
        }
        // the level-by-level reduction written out, for every count up to 40
        let levels = |p: &[f64]| -> f64 {
            let mut p = p.to_vec();
            if p.is_empty() {
                return 0.0;
            }
            while p.len() > 1 {
                p = p
                    .chunks(2)
                    .map(|c| c.iter().copied().reduce(|a, b| a + b).unwrap())
                    .collect();
            }
            p[0]
        };
        for m in 0..=t.len() {
            let got = tree_sum(t[..m].iter().copied());
            assert_eq!(got.to_bits(), levels(&t[..m]).to_bits(), "{m} terms");
            let plain: f64 = t[..m].iter().sum();
            assert!((got - plain).abs() <= 1e-15 * plain.abs(), "{m} terms");
        }
    }

    /// The unrolled fixed-size steps give the row-by-row product to the bit.
    #[test]
    fn fixed_size_steps_equal_the_row_by_row_product() {
        // counter-based pseudo-random numbers in [-0.5, 0.5)
        let mut i = 0.0f64;
        let mut rnd = || {
            i += 1.0;
            ((i * 12.9898).sin() * 43758.5453).fract() * 0.5
        };
        for ns in [4usize, 6, 8] {
            let ad = nalgebra::DMatrix::from_fn(ns, ns, |_, _| rnd());
            let p = Prop::new(
                &ad,
                (0..ns).map(|_| rnd()).collect(),
                (0..ns).map(|_| rnd()).collect(),
            );
            let x: Vec<f64> = (0..ns).map(|_| rnd()).collect();
            let (mut fast, mut slow) = (vec![0.0; ns], vec![0.0; ns]);
            match ns {
                4 => p.apply::<4>(&x, &mut fast, 0.3, -1.7),
                6 => p.apply::<6>(&x, &mut fast, 0.3, -1.7),
                _ => p.apply::<8>(&x, &mut fast, 0.3, -1.7),
            }
            p.apply_rows(&x, &mut slow, 0.3, -1.7);
            assert_eq!(fast, slow, "{ns} states");
            // and the row-major matrix itself: A x + bu u + bc fc
            let want = &ad * nalgebra::DVector::from_vec(x.clone());
            for r in 0..ns {
                let w = want[r] + p.bu[r] * 0.3 - p.bc[r] * 1.7;
                assert!((fast[r] - w).abs() < 1e-12, "{ns}: row {r}");
            }
        }
    }

    fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
        (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
    }

    /// The piecewise-exact backlash and the extrapolated hardening on 4 sub-steps against
    /// the fine-step RK4 plant: the effect's change of the motor velocity is reproduced to
    /// within 40 % in the time domain (the linear chain alone misses all of it; impacts make
    /// the trajectories sensitive, the FRFs agree far closer).
    #[test]
    fn spring_nonlinearities_match_the_fine_step_plant() {
        for e in spring_nonlinearities_at(2000.0, 4) {
            assert!(e.effect > 0.0 && e.time < 0.4 * e.effect, "{e:?}");
        }
    }

    /// The sub-step is a time ([`crate::diagnose::substeps_at`]): at 4 kHz on 2 sub-steps
    /// a sample, the error at the excitation's tones (what an FRF reads) is within 1.5x of
    /// the error at 2 kHz on 4 for a backlash (measured 1.2x; in the time domain its
    /// impacts make any comparison a lottery: 1 or 2 sub-steps at 2 kHz err less than 4).
    /// A cubic spring's error is the [`Hermite`] step's, fourth order: under 1e-3 at both
    /// rates (measured 4.1e-5 and 9.1e-5; the held torque it replaced erred 4.7e-2 and
    /// 4.4e-2 here).
    #[test]
    fn the_sub_step_is_a_time_not_a_fraction_of_the_sample() {
        let sub = |fs: f64| crate::diagnose::substeps_at(4, fs);
        assert_eq!(
            (sub(2000.0), sub(4000.0), sub(8000.0), sub(610.0)),
            (4, 2, 1, 4)
        );
        let slow = spring_nonlinearities_at(2000.0, sub(2000.0));
        let fast = spring_nonlinearities_at(4000.0, sub(4000.0));
        for (a, b) in slow.iter().zip(&fast) {
            match a.nl {
                Nl::Backlash { .. } => {
                    assert!(b.tones > 0.0 && b.tones < 1.5 * a.tones, "{a:?} vs {b:?}")
                }
                _ => assert!(a.tones < 1e-3 && b.tones < 1e-3, "{a:?} vs {b:?}"),
            }
        }
    }

    /// A cubic spring's step converges at fourth order: halving the sub-step divides the
    /// tone error against the fine-step plant by 16 (at least 8 asserted; measured 28 from
    /// 4 to 8 sub-steps at 2 kHz, where the second-order held torque gave about 4).
    #[test]
    fn cubic_springs_converge_at_fourth_order() {
        let coarse = spring_nonlinearities_at(2000.0, 4);
        let fine = spring_nonlinearities_at(2000.0, 8);
        let (a, b) = (&coarse[1], &fine[1]);
        assert!(matches!(a.nl, Nl::Hardening { .. }));
        assert!(b.tones > 0.0 && a.tones > 8.0 * b.tones, "{a:?} vs {b:?}");
    }

    /// The tones [Hz] and phases [rad] of the spring tests' excitation (whole cycles in
    /// 1 s).
    const TONES: [(f64, f64); 5] = [
        (7.0, 0.0),
        (37.0, 1.0),
        (211.0, 2.0),
        (411.0, 0.5),
        (587.0, 2.5),
    ];

    /// How far [`simulate`] is from the fine-step plant with a spring nonlinearity.
    #[derive(Debug)]
    struct SpringError {
        /// The effect (read in the failure messages).
        #[allow(dead_code)]
        nl: Nl,
        /// RMS change of the motor velocity the effect makes, and the simulation's RMS
        /// error [rad/s].
        effect: f64,
        time: f64,
        /// The relative error of the motor velocity at the excitation's tones (root of the
        /// sum over the tones of `|sim - ref|^2 / |ref|^2`, last two thirds of the record).
        tones: f64,
    }

    fn spring_nonlinearities_at(fs: f64, sub: usize) -> Vec<SpringError> {
        let chain = Chain::new(
            vec![3.6e-3, 5.1e-3, 17.2e-3],
            vec![2.9e4, 171.0],
            vec![0.47, 0.018],
        )
        .unwrap();
        let u: Vec<f64> = (0..(3.0 * fs) as usize)
            .map(|k| {
                let t = k as f64 / fs;
                TONES
                    .iter()
                    .map(|(f, p)| 0.03 * (2.0 * std::f64::consts::PI * f * t + p).sin())
                    .sum()
            })
            .collect();
        let lin = LinExt::nominal(chain.clone());
        let plain = simulate(&lin, Nl::None, &u, fs, sub).vel;
        let x = simulate(&lin, Nl::None, &u, fs, sub).defl_rms;
        let mut out = Vec::new();
        for (nl, effects) in [
            (
                Nl::Backlash { k: 0, g: x[0] },
                Effects {
                    backlash: Some(Backlash {
                        coupling: 0,
                        half_gap_rad: x[0],
                    }),
                    ..Effects::default()
                },
            ),
            (
                Nl::Hardening {
                    k: 0,
                    xref: 1.5 * x[0],
                },
                Effects {
                    hardening_stiffness: Some(Hardening {
                        coupling: 0,
                        x_ref_rad: 1.5 * x[0],
                    }),
                    ..Effects::default()
                },
            ),
        ] {
            let spec = PlantSpec {
                chain: chain.clone(),
                effects,
            };
            let want = reference(&spec, &u, fs);
            let got = simulate(&lin, nl, &u, fs, sub).vel;
            let tone = |v: &[f64], f: f64| -> Complex64 {
                let n0 = v.len() / 3;
                let w = -2.0 * std::f64::consts::PI * f / fs;
                (n0..v.len())
                    .map(|i| v[i] * Complex64::from_polar(1.0, w * i as f64))
                    .sum()
            };
            let tones = TONES
                .iter()
                .map(|&(f, _)| {
                    let (got, want) = (tone(&got, f), tone(&want, f));
                    (got - want).norm_sqr() / want.norm_sqr()
                })
                .sum::<f64>()
                .sqrt();
            out.push(SpringError {
                nl,
                effect: rms_diff(&plain, &want),
                time: rms_diff(&got, &want),
                tones,
            });
        }
        out
    }

    /// A cubic spring to the ground on the load of a 2-mass chain against an independent
    /// reference: RK4 of the full equations on 200 steps per sample. And the centred start
    /// of a free chain: the linear free chain (k3 = 0) then does not drift (its position's
    /// mean over the last quarter equals the first's).
    #[test]
    fn a_cubic_ground_spring_matches_a_fine_rk4() {
        let fs = 1000.0;
        let chain = Chain::new(vec![1e-3, 2e-3], vec![400.0], vec![0.02]).unwrap();
        let n_samples = 4000;
        let u: Vec<f64> = (0..n_samples)
            .map(|k| {
                let t = k as f64 / fs;
                [
                    (5.0, 0.3),
                    (11.0, 1.0),
                    (23.0, 2.0),
                    (61.0, 0.5),
                    (140.0, 2.5),
                ]
                .iter()
                .map(|(f, p)| 0.02 * (2.0 * std::f64::consts::PI * f * t + p).sin())
                .sum()
            })
            .collect();
        let lin = LinExt::nominal(chain.clone());
        let free = simulate(&lin, Nl::GroundCubic { k3: 0.0 }, &u, fs, 4);
        let quarter = n_samples / 4;
        let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
        let rms = (free.pos.iter().map(|p| p * p).sum::<f64>() / n_samples as f64).sqrt();
        let drift = (mean(&free.pos[3 * quarter..]) - mean(&free.pos[..quarter])).abs();
        assert!(drift < 0.02 * rms, "drift {drift} of RMS {rms}");
        // equivalent stiffness 3 k3 sigma² = J_t (2 pi 8 Hz)²: a ground resonance near 8 Hz
        let jt = chain.total_inertia();
        let k3 = 0.3 * jt * (2.0 * std::f64::consts::PI * 5.0).powi(2) / (3.0 * rms * rms);
        // an undamped rigid mode on a cubic spring never forgets its start (its free
        // oscillation's frequency depends on its amplitude): damped to the ground, 30 % of
        // critical at the equivalent stiffness, the reference started where the
        // simulation starts
        let b = 0.6 * jt * (0.3f64).sqrt() * 2.0 * std::f64::consts::PI * 5.0;
        let mut lin = lin;
        lin.motor_b = b;
        let got = simulate(&lin, Nl::GroundCubic { k3 }, &u, fs, 8).vel;
        // the linear chain from the same (centred) start
        let free = simulate(&lin, Nl::GroundCubic { k3: 0.0 }, &u, fs, 8);
        // the reference: x = (q1, q2, v1, v2)
        let (j1, j2, c, d) = (1e-3, 2e-3, 400.0, 0.02);
        let f = |x: [f64; 4], tq: f64| {
            let spring = c * (x[1] - x[0]) + d * (x[3] - x[2]);
            [
                x[2],
                x[3],
                (tq + spring - b * x[2]) / j1,
                (-spring - k3 * x[1].powi(3)) / j2,
            ]
        };
        // from the simulation's start: the chain centred ([`centred_start`])
        let x0 = centred_start(&chain, b, &u, fs);
        let mut x = [x0[0], x0[1], x0[2], x0[3]];
        let steps = 200;
        let h = 1.0 / fs / steps as f64;
        let mut want = Vec::with_capacity(n_samples);
        for &tq in &u {
            want.push(x[2]);
            for _ in 0..steps {
                let add = |a: [f64; 4], b: [f64; 4], s: f64| {
                    [
                        a[0] + s * b[0],
                        a[1] + s * b[1],
                        a[2] + s * b[2],
                        a[3] + s * b[3],
                    ]
                };
                let k1 = f(x, tq);
                let k2 = f(add(x, k1, h / 2.0), tq);
                let k3_ = f(add(x, k2, h / 2.0), tq);
                let k4 = f(add(x, k3_, h), tq);
                for i in 0..4 {
                    x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3_[i] + k4[i]);
                }
            }
        }
        // after the start's transient (1/e time J_t/b = 0.09 s)
        let late = n_samples / 4;
        let effect = rms_diff(&free.vel[late..], &want[late..]);
        let err = rms_diff(&got[late..], &want[late..]);
        assert!(
            effect > 0.0 && err < 0.02 * effect,
            "error {err} vs effect {effect}"
        );
    }

    /// A free chain with viscous friction to the ground starts centred too
    /// ([`centred_start`]): under a cubic ground spring of zero size its motor position's
    /// mean over the record is zero (within 2 % of its RMS), where a start from rest
    /// leaves the offset the excitation's start gives it (asserted: at least 10 %).
    #[test]
    fn a_damped_free_chain_starts_centred() {
        let fs = 1000.0;
        let chain = Chain::new(vec![1e-3, 2e-3], vec![400.0], vec![0.02]).unwrap();
        let u: Vec<f64> = (0..4000)
            .map(|k| {
                let t = k as f64 / fs;
                [(3.0, 0.3), (11.0, 1.0), (61.0, 0.5)]
                    .iter()
                    .map(|(f, p)| 0.02 * (2.0 * std::f64::consts::PI * f * t + p).sin())
                    .sum()
            })
            .collect();
        let mut lin = LinExt::nominal(chain.clone());
        // the rigid body's time constant J_t / b: 0.3 s of the record's 4 s
        lin.motor_b = chain.total_inertia() / 0.3;
        let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
        let rms = |x: &[f64]| (x.iter().map(|p| p * p).sum::<f64>() / x.len() as f64).sqrt();
        let centred = simulate(&lin, Nl::GroundCubic { k3: 0.0 }, &u, fs, 2).pos;
        let from_rest = simulate(&lin, Nl::None, &u, fs, 2).pos;
        let m = mean(&centred).abs();
        let r = rms(&centred);
        assert!(m < 0.02 * r, "mean {m} of RMS {r}");
        let m0 = mean(&from_rest).abs();
        assert!(m0 > 0.1 * rms(&from_rest), "from rest: mean {m0}");
    }

    /// The shortened stepped sine gives the full record's lines (a linear chain, noise
    /// free: the steady state is the same) in the same order, from a fraction of the
    /// samples.
    #[test]
    fn a_shortened_stepped_sine_gives_the_same_lines() {
        // the rigid body settles in J_t/b = 0.06 s, well within a block's settle periods
        // (with a slower pole the transient left after them differs between the two)
        let (rec, lin) = stepped_recording(6, 3);
        let fs = rec.sample_rate_hz;
        // the measured motion (here: zeros) is cut alike, so the simulation knows its column
        let short = shortened_stepped(&rec, 1).unwrap();
        assert_eq!(short.position_rad.as_ref().unwrap().len(), short.len());
        assert!(
            short.len() * 2 < rec.len(),
            "{} of {}",
            short.len(),
            rec.len()
        );
        let keep: Vec<usize> = (0..5).collect();
        let full_out = simulate(&lin, Nl::None, &rec.torque_cmd_nm, fs, 2);
        let short_out = simulate(&lin, Nl::None, &short.torque_cmd_nm, fs, 2);
        let full = sim_frf(&rec, None, &keep, &full_out).unwrap();
        let cut = sim_frf(&short, None, &keep, &short_out).unwrap();
        for (a, b) in full.iter().zip(&cut) {
            assert!((a / b - 1.0).norm() < 1e-3, "{a} vs {b}");
        }
        // not a stepped sine: nothing to shorten
        let mut plain = rec.clone();
        plain.sidecar.excitation = None;
        assert!(shortened_stepped(&plain, 1).is_none());
    }

    /// A stepped-sine recording of a 2-mass chain with a zero position column, and the
    /// chain (motor viscous friction: the rigid body settles within a block).
    /// The stepped case of the tests below, and its gear's RMS deflection without effect
    /// [rad] (the scale of the spring effects' parameters).
    fn stepped_case() -> (Recording, LinExt, f64) {
        let (rec, lin) = stepped_recording(4, 2);
        let x = simulate(&lin, Nl::None, &rec.torque_cmd_nm, rec.sample_rate_hz, 1).defl_rms[0];
        (rec, lin, x)
    }

    /// Every effect the simulation carries, at sizes that act on [`stepped_case`] (`x`:
    /// its RMS deflection).
    fn every_effect(x: f64) -> [Nl; 5] {
        [
            Nl::None,
            Nl::Friction { tc: 0.1 },
            Nl::Backlash { k: 0, g: 0.5 * x },
            Nl::Hardening { k: 0, xref: x },
            Nl::GroundCubic { k3: 1e3 },
        ]
    }

    /// A stepped sine at 3 .. 243 Hz (1 kHz; `periods` measured and `settle` settle
    /// periods per block) as a recording with a zero position column, and a 2-mass chain
    /// whose motor viscous friction lets the rigid body settle in 0.06 s.
    fn stepped_recording(periods: usize, settle: usize) -> (Recording, LinExt) {
        use crate::excitation::SteppedSineDesign;
        let fs = 1000.0;
        let stepped = SteppedSineDesign {
            sample_rate_hz: fs,
            frequencies_hz: vec![3.0, 9.0, 27.0, 81.0, 243.0],
            min_period_samples: 100,
            periods,
            settle_periods: settle,
            peak_limit_nm: 1.0,
            rms_limit_nm: 1.0,
        }
        .generate()
        .unwrap();
        let n = stepped.signal.len();
        let rec = Recording::of_position(
            fs,
            stepped.signal.clone(),
            vec![0.0; n],
            Some(stepped.info()),
        );
        let chain = Chain::new(vec![1e-3, 2e-3], vec![400.0], vec![0.05]).unwrap();
        let mut lin = LinExt::nominal(chain);
        lin.motor_b = 0.05;
        (rec, lin)
    }

    /// [`simulate_lanes`] on the plain or the AVX2 time loop (3 sub-steps).
    fn lanes_on(wide: bool, lin: &LinExt, nl: Nl, us: &[&[f64]], fs: f64) -> Vec<SimOut> {
        let s = setup(lin, nl, fs, 3);
        let starts = vec![vec![0.0; s.bm.len()]; us.len()];
        let mut outs = vec![SimOut::default(); us.len()];
        let job = Job {
            s: &s,
            nl,
            us,
            starts: &starts,
            record: Record::Both,
        };
        integrate_on(wide, &job, &mut outs);
        outs
    }

    /// The AVX2 time loop gives the plain one's records to the bit, for every effect and
    /// chains of 1 to 5 bodies (2 to 8 states unrolled, 10 of any size; the hardening of
    /// 2 bodies leaves the bounds: NaN in both).
    #[test]
    fn wide_integration_equals_the_plain_one() {
        let (rec, _, x) = stepped_case();
        let (fs, u) = (rec.sample_rate_hz, &rec.torque_cmd_nm);
        let short = &u[..u.len() / 3];
        for n in 1..=5 {
            let chain = Chain::new(
                (0..n).map(|i| 1e-3 * (1.0 + i as f64)).collect(),
                (1..n).map(|i| 400.0 / i as f64).collect(),
                (1..n).map(|i| 0.05 / i as f64).collect(),
            )
            .unwrap();
            let mut lin = LinExt::nominal(chain);
            lin.motor_b = 0.05;
            for nl in every_effect(x) {
                let plain = lanes_on(false, &lin, nl, &[u, short], fs);
                let wide = lanes_on(true, &lin, nl, &[u, short], fs);
                for (p, w) in plain.iter().zip(&wide) {
                    assert_eq!(bits(&p.pos), bits(&w.pos), "{n} bodies, {nl:?}");
                    assert_eq!(bits(&p.vel), bits(&w.vel), "{n} bodies, {nl:?}");
                    assert_eq!(bits(&p.defl_rms), bits(&w.defl_rms), "{n}, {nl:?}");
                }
            }
        }
    }

    /// Nanoseconds per simulated sub-step of one lane, plain and AVX2, for 2 and 3 masses
    /// and each effect (`cargo test --release -p flexid-core probe_sub_step_time --
    /// --ignored --nocapture`; the least of 4 runs, two rounds).
    #[test]
    #[ignore]
    fn probe_sub_step_time() {
        let (rec, lin) = stepped_recording(40, 3);
        let (fs, u) = (rec.sample_rate_hz, &rec.torque_cmd_nm);
        let chain3 = Chain::new(vec![1e-3, 2e-3, 3e-3], vec![400.0, 300.0], vec![0.05, 0.04]);
        let mut lin3 = LinExt::nominal(chain3.unwrap());
        lin3.motor_b = 0.05;
        let x = simulate(&lin, Nl::None, u, fs, 1).defl_rms[0];
        for (name, lin) in [("2m", &lin), ("3m", &lin3)] {
            for nl in [
                Nl::Hardening { k: 0, xref: x },
                Nl::GroundCubic { k3: 1e3 },
                Nl::Friction { tc: 0.1 },
                Nl::Backlash { k: 0, g: 0.5 * x },
            ] {
                let mut line = format!("{name} {nl:?}:");
                for round in 0..2 {
                    for wide in [false, true] {
                        let mut best = f64::INFINITY;
                        for _ in 0..4 {
                            let t = std::time::Instant::now();
                            lanes_on(wide, lin, nl, &[u, u], fs);
                            best = best.min(t.elapsed().as_secs_f64());
                        }
                        let ns = best * 1e9 / (2.0 * 3.0 * u.len() as f64);
                        let isa = if wide { "avx2" } else { "plain" };
                        line += &format!(" r{round} {isa}: {ns:.2}");
                    }
                }
                println!("{line} ns per lane-substep ({} samples)", u.len());
            }
        }
    }

    fn bits(x: &[f64]) -> Vec<u64> {
        x.iter().map(|v| v.to_bits()).collect()
    }

    /// Excitations stepped together give each one's simulation alone to the bit, for every
    /// effect, with lanes of different lengths, and a lane that leaves the bounds (a
    /// hardening far beyond the step) stops alone with a NaN output.
    #[test]
    fn lanes_equal_single_simulations() {
        let (rec, lin, x) = stepped_case();
        let (fs, u) = (rec.sample_rate_hz, &rec.torque_cmd_nm);
        let big: Vec<f64> = u.iter().map(|t| 1e4 * t).collect();
        let short = &u[..u.len() / 3];
        for nl in every_effect(x) {
            let us: [&[f64]; 3] = [u, short, &big];
            let lanes = simulate_lanes(&lin, nl, &us, fs, 3);
            for (lane, u) in lanes.iter().zip(us) {
                let alone = simulate(&lin, nl, u, fs, 3);
                assert_eq!(bits(&lane.pos), bits(&alone.pos), "{nl:?}");
                assert_eq!(bits(&lane.vel), bits(&alone.vel), "{nl:?}");
                assert_eq!(bits(&lane.defl_rms), bits(&alone.defl_rms), "{nl:?}");
                assert_eq!(lane.pos.len(), u.len());
            }
        }
        let blown = simulate_lanes(&lin, Nl::Hardening { k: 0, xref: 1e-9 }, &[u, short], fs, 1);
        assert!(blown[1].pos.iter().all(|p| p.is_nan()));
        assert_eq!(blown[1].pos.len(), short.len());
    }

    /// A simulation recording one motion into kept buffers (left over from other, longer
    /// and blown-up simulations) records it to the bit as [`simulate_lanes`] does, and
    /// leaves the other empty; a blown-up lane is NaN in the recorded motion only.
    #[test]
    fn recording_one_motion_into_kept_buffers_equals_fresh_lanes() {
        let (rec, lin, x) = stepped_case();
        let (fs, u) = (rec.sample_rate_hz, &rec.torque_cmd_nm);
        let short = &u[..u.len() / 3];
        let mut kept = Vec::new();
        for nl in [
            Nl::Hardening { k: 0, xref: 1e-9 },
            Nl::Friction { tc: 0.1 },
            Nl::Backlash { k: 0, g: 0.5 * x },
            Nl::Hardening { k: 0, xref: x },
        ] {
            for (us, record) in [
                ([short, u], Record::Position),
                ([u, short], Record::Velocity),
                ([short, short], Record::Both),
            ] {
                let fresh = simulate_lanes(&lin, nl, &us, fs, 2);
                simulate_lanes_into(&lin, nl, &us, fs, 2, record, &mut kept);
                assert_eq!(kept.len(), 2);
                for (k, f) in kept.iter().zip(&fresh) {
                    let (want_pos, want_vel) = match record {
                        Record::Position => (bits(&f.pos), vec![]),
                        Record::Velocity => (vec![], bits(&f.vel)),
                        Record::Both => (bits(&f.pos), bits(&f.vel)),
                    };
                    assert_eq!(bits(&k.pos), want_pos, "{nl:?} {record:?}");
                    assert_eq!(bits(&k.vel), want_vel, "{nl:?} {record:?}");
                    assert_eq!(bits(&k.defl_rms), bits(&f.defl_rms), "{nl:?} {record:?}");
                }
            }
        }
    }

    /// The simulated response's FRF equals, to the bit, the measurement's estimator on a
    /// copy of the recording holding the simulated motion (what `sim_frf` did before it
    /// estimated against the recording itself), for the whole record and for a shortened
    /// one, by position and by velocity.
    #[test]
    fn sim_frf_equals_the_estimate_of_a_copied_recording() {
        let (rec, lin, _) = stepped_case();
        let short = shortened_stepped(&rec, 1).unwrap();
        for rec in [rec, short] {
            let out = simulate(
                &lin,
                Nl::Friction { tc: 0.05 },
                &rec.torque_cmd_nm,
                1000.0,
                2,
            );
            for velocity in [false, true] {
                let mut rec = rec.clone();
                let mut copy = rec.clone();
                copy.torque_actual_nm = None;
                if velocity {
                    rec.position_rad = None;
                    rec.velocity_rad_s = Some(vec![0.0; rec.len()]);
                    copy.position_rad = None;
                    copy.velocity_rad_s = Some(out.vel.clone());
                } else {
                    copy.position_rad = Some(out.pos.clone());
                }
                let naive = crate::analysis::estimate_frf(&copy, None).unwrap().frf.h;
                let keep: Vec<usize> = (0..naive.len()).collect();
                let fast = sim_frf(&rec, None, &keep, &out).unwrap();
                let b = |h: &[Complex64]| -> Vec<(u64, u64)> {
                    h.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
                };
                assert_eq!(b(&fast), b(&naive), "velocity {velocity}");
            }
        }
    }
}

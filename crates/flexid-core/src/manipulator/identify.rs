//! Identification of the spring-damper parameters `theta` from measured FRF matrices at
//! several poses: the paper's cost ([`super::cost`]) minimised from many starts (60 in the
//! paper), each start a local fit with analytic derivatives ([`super::frf`]), the starts
//! spread over all cores.
//!
//! The local fit. The cost is a sum over elements of `p`-means, `V = sum_e S_e^(1/p)` with
//! `S_e = sum_k alpha_k |E_k|^p / sum alpha`: not a sum of squares, so it is minimised by
//! majorisation (iteratively reweighted least squares): at the current `theta_0`, the
//! concave map `S -> S^(1/p)` and, for `p < 2`, `E^2 -> |E|^p`, lie below their tangents,
//! so `V(theta) <= const + sum_e sum_k w_ek E_k(theta)^2` with
//! `w_ek = alpha_k |E_k(theta_0)|^(p-2) S_e(theta_0)^(1/p-1) / (2 sum alpha)`, equality at
//! `theta_0`. Levenberg-Marquardt steps on that weighted sum of squares (Jacobian rows
//! from the FRF's analytic derivatives) lower `V`; the weights are taken anew at every
//! accepted step ([`reweighted_lm`]), so the fit is Levenberg-Marquardt on `V` itself with
//! the majoriser's curvature, and ends at a stationary point of `V` (where the gradients
//! of the two agree).
//!
//! The parameters are the logarithms of the stiffnesses and dampings (all positive, all of
//! order one in scale).

use super::cost::{abs_pow, db_of, Cost, Weighting, DB_PER_NEPER};
use super::frf::{FrfPlan, LINES_PER_BATCH};
use super::pose::RigidPose;
use super::sampled::SampledPose;
use super::springs::Flexibilities;
use super::ManipulatorError;
use crate::lsq::NormalEquations;
use nalgebra::DMatrix;
use num_complex::Complex64;
use rand::{Rng, SeedableRng};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Which model FRF is compared with the measurement.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum FrfForm {
    /// The continuous-time model ([`FrfPlan`]).
    #[default]
    Continuous,
    /// The sampled plant's ([`SampledPose`]: torque held, speed backward-differenced at
    /// `fs_hz`), what an estimate from a drive's samples converges to
    /// (`../shared/design/multiaxis.md`, fact 3). The fit evaluates the continuous model
    /// times the ratio sampled / continuous taken at the start of each reweighting round
    /// (smooth in frequency: both share the poles, `z = e^(s T)`); at the fit's end the
    /// ratio is the end's, so the model compared is the sampled one.
    Sampled {
        /// The drive's sample rate [Hz].
        fs_hz: f64,
    },
}

/// Choices of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyOptions {
    /// Number of starts (the paper: 60). Start 0 is the nominal `theta` itself.
    pub starts: usize,
    /// The starts spread log-uniformly (a Latin hypercube) over `[nominal / spread,
    /// nominal * spread]` per parameter [-].
    pub spread: f64,
    /// Seed of the start design.
    pub seed: u64,
    /// Worker threads; 0: every core.
    pub threads: usize,
    /// Model evaluations (cost passes) of one local fit at most: per start in the
    /// continuous form, per round in the sampled one.
    pub evals_per_round: usize,
    /// Rounds per start at most in the sampled form (the sampled ratio refreshed between
    /// them); the continuous form has one.
    pub rounds: usize,
    /// The model FRF compared.
    pub form: FrfForm,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        IdentifyOptions {
            starts: 60,
            spread: 3.0,
            seed: 1,
            threads: 0,
            evals_per_round: 400,
            rounds: 60,
            form: FrfForm::Continuous,
        }
    }
}

/// One start's run.
#[derive(Debug, Clone, PartialEq)]
pub struct StartOutcome {
    /// Where it started.
    pub start: Flexibilities,
    /// Where it ended.
    pub end: Flexibilities,
    /// The paper's cost `V` at the end [dB].
    pub cost: f64,
    /// Model evaluations (every pose's FRF at every line) it used.
    pub evaluations: usize,
    /// `None`, or why the start was abandoned (a singular model on a line, say).
    pub failure: Option<String>,
}

/// The result of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The parameters of the lowest final cost.
    pub best: Flexibilities,
    /// Its cost `V` [dB] and per pose.
    pub cost: f64,
    pub cost_per_pose: Vec<f64>,
    /// Every start's run, in start order (the paper's Figure 5).
    pub starts: Vec<StartOutcome>,
    /// The starts that reached the best minimum: final cost within [`GOOD_COST_RATIO`]
    /// of the best.
    pub good: Vec<usize>,
    /// Per parameter (`k` then `c`, in the pose's pair order): the relative spread
    /// `max / min - 1` of its final value over the good starts [-].
    pub spread: Vec<f64>,
    /// Per parameter: the standard uncertainty of its logarithm from the measurement's
    /// variance (the Fisher information of the variance-weighted log-magnitudes,
    /// `(J^T J)^-1`; about the relative uncertainty where small) [-]; `None` without
    /// variance weights ([`super::Weighting::InverseVariance`]). Infinite where the data
    /// carry no information on it.
    pub std_ln: Option<Vec<f64>>,
}

/// A parameter is reported "not identifiable" when the measurement does not fix it within
/// a factor of two at one standard uncertainty (`std_ln > ln 2`): its value then says
/// nothing a reader could use. A reporting definition, not a tuned constant (the fit does
/// not depend on it).
pub const IDENTIFIABLE_STD_LN: f64 = std::f64::consts::LN_2;

impl Identification {
    /// Whether parameter `j` is identified (its `std_ln` at most [`IDENTIFIABLE_STD_LN`]);
    /// `None` without variance weights.
    pub fn identifiable(&self, j: usize) -> Option<bool> {
        self.std_ln
            .as_ref()
            .map(|s| s[j].is_finite() && s[j] <= IDENTIFIABLE_STD_LN)
    }
}

/// Final costs within this factor of the best count as the same minimum. The cost is an
/// RMS of dB errors, so this is "within 10 % of the best fit's RMS": runs at the same
/// minimum agree to the solver's tolerance, and the local minima of such fits lie several
/// times higher (`../shared/design/multiaxis.md`, fact 6: ten times). A definition for the
/// report, not a tuned constant: the best parameters do not depend on it.
pub const GOOD_COST_RATIO: f64 = 1.1;

/// The model FRF matrices of `theta` in `form` at every pose and line of `cost`.
pub fn model_frf(
    poses: &[RigidPose],
    cost: &Cost,
    theta: &Flexibilities,
    form: FrfForm,
) -> Result<Vec<Vec<DMatrix<Complex64>>>, ManipulatorError> {
    poses
        .iter()
        .zip(&cost.f_hz)
        .map(|(pose, f)| match form {
            FrfForm::Continuous => Ok(FrfPlan::new(pose).frf(f, theta)?.g),
            FrfForm::Sampled { fs_hz } => {
                let s = SampledPose::new(pose, theta, fs_hz)?;
                f.iter().map(|&f| s.frf(f)).collect()
            }
        })
        .collect()
}

/// Identifies `theta` from the measurement in `cost` (one [`RigidPose`] per measured pose,
/// in the same order), starting around `nominal`.
pub fn identify(
    poses: &[RigidPose],
    cost: &Cost,
    nominal: &Flexibilities,
    opts: &IdentifyOptions,
) -> Result<Identification, ManipulatorError> {
    check(poses, cost, nominal)?;
    let starts = start_design(nominal, opts);
    let outcomes = run_starts(poses, cost, &starts, opts);
    let best = (0..outcomes.len())
        .filter(|&i| outcomes[i].failure.is_none())
        .min_by(|&a, &b| outcomes[a].cost.total_cmp(&outcomes[b].cost))
        .ok_or_else(|| ManipulatorError::NoStartConverged {
            starts: outcomes.len(),
            first_failure: outcomes
                .first()
                .and_then(|o| o.failure.clone())
                .unwrap_or_default(),
        })?;
    let best_cost = outcomes[best].cost;
    let good: Vec<usize> = (0..outcomes.len())
        .filter(|&i| {
            outcomes[i].failure.is_none() && outcomes[i].cost <= GOOD_COST_RATIO * best_cost
        })
        .collect();
    let spread = parameter_spread(&outcomes, &good);
    let best_theta = outcomes[best].end.clone();
    let cost_per_pose = cost.per_pose(&model_frf(poses, cost, &best_theta, opts.form)?);
    let std_ln = match cost.spec.weighting {
        Weighting::InverseVariance => Some(log_uncertainty(poses, cost, &best_theta, opts.form)),
        Weighting::Uniform => None,
    };
    Ok(Identification {
        best: best_theta,
        cost: best_cost,
        cost_per_pose,
        starts: outcomes,
        good,
        spread,
        std_ln,
    })
}

/// The standard uncertainty of each parameter's logarithm at `theta`: the residuals
/// `E / sigma_dB` of every line of every term (with variance weights `alpha = 1/sigma^2`),
/// their Jacobian `J` in the logarithms, `sqrt(diag((J^T J)^-1))` through the symmetric
/// eigendecomposition (a direction with no information gives infinity, not a NaN).
fn log_uncertainty(
    poses: &[RigidPose],
    cost: &Cost,
    theta: &Flexibilities,
    form: FrfForm,
) -> Vec<f64> {
    let mut fit = Fit::new(poses, cost);
    let log = theta.to_log();
    let np = log.len();
    fit.set_theta(&log);
    if fit.refresh_form(form).is_none() {
        return vec![f64::INFINITY; np];
    }
    for (w, t) in fit.w.iter_mut().zip(&cost.terms) {
        w.copy_from_slice(&t.alpha);
    }
    let (mut jtj, mut jtr) = (vec![0.0; np * np], vec![0.0; np]);
    if !fit.normal_after_cost(&mut (), &mut jtj, &mut jtr) {
        return vec![f64::INFINITY; np];
    }
    let eig = DMatrix::from_row_slice(np, np, &jtj).symmetric_eigen();
    let largest = eig.eigenvalues.amax();
    (0..np)
        .map(|j| {
            let var: f64 = (0..np)
                .map(|i| {
                    let l = eig.eigenvalues[i];
                    // a direction below round-off of the largest carries no information
                    if l <= largest * 1e-14 {
                        if eig.eigenvectors[(j, i)].abs() > 1e-6 {
                            f64::INFINITY
                        } else {
                            0.0
                        }
                    } else {
                        eig.eigenvectors[(j, i)].powi(2) / l
                    }
                })
                .sum();
            var.sqrt()
        })
        .collect()
}

/// The poses match the measurement and `nominal` has one pair per spring of each pose.
fn check(
    poses: &[RigidPose],
    cost: &Cost,
    nominal: &Flexibilities,
) -> Result<(), ManipulatorError> {
    if poses.len() != cost.f_hz.len() {
        return Err(ManipulatorError::Length {
            what: "poses",
            expected: cost.f_hz.len(),
            got: poses.len(),
        });
    }
    for pose in poses {
        if pose.springs.len() != nominal.pairs() {
            return Err(ManipulatorError::Length {
                what: "nominal spring-damper pairs",
                expected: pose.springs.len(),
                got: nominal.pairs(),
            });
        }
        if pose.axes() != cost.axes {
            return Err(ManipulatorError::Length {
                what: "axes of a pose",
                expected: cost.axes,
                got: pose.axes(),
            });
        }
    }
    Flexibilities::new(
        nominal.stiffness_nm_per_rad.clone(),
        nominal.damping_nms_per_rad.clone(),
    )?;
    if nominal.damping_nms_per_rad.contains(&0.0) {
        return Err(ManipulatorError::NotPositive {
            what: "nominal damping_nms_per_rad (the fit's parameters are logarithms)",
            index: nominal
                .damping_nms_per_rad
                .iter()
                .position(|&c| c == 0.0)
                .unwrap_or(0),
            value: 0.0,
        });
    }
    Ok(())
}

/// The starts: the nominal parameters, then a Latin hypercube in the logarithms over
/// `nominal x [1/spread, spread]` (each parameter's range cut into `starts - 1` strata,
/// each stratum used once, in a random order per parameter).
pub fn start_design(nominal: &Flexibilities, opts: &IdentifyOptions) -> Vec<Vec<f64>> {
    let base = nominal.to_log();
    let mut rng = rand::rngs::StdRng::seed_from_u64(opts.seed);
    let others = opts.starts.saturating_sub(1);
    let half = opts.spread.max(1.0).ln();
    let mut starts = vec![base.clone()];
    let mut strata: Vec<Vec<usize>> = Vec::with_capacity(base.len());
    for _ in 0..base.len() {
        let mut s: Vec<usize> = (0..others).collect();
        for i in (1..s.len()).rev() {
            s.swap(i, rng.random_range(0..=i));
        }
        strata.push(s);
    }
    for i in 0..others {
        let start = base
            .iter()
            .zip(&strata)
            .map(|(b, s)| {
                let u = (s[i] as f64 + rng.random_range(0.0..1.0)) / others as f64;
                b + half * (2.0 * u - 1.0)
            })
            .collect();
        starts.push(start);
    }
    starts.truncate(opts.starts.max(1));
    starts
}

/// Every start's local fit, on the worker threads (each takes the next start not taken).
fn run_starts(
    poses: &[RigidPose],
    cost: &Cost,
    starts: &[Vec<f64>],
    opts: &IdentifyOptions,
) -> Vec<StartOutcome> {
    let threads = if opts.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        opts.threads
    }
    .clamp(1, starts.len().max(1));
    let next = AtomicUsize::new(0);
    let work = || {
        let mut fit = Fit::new(poses, cost);
        let mut done = Vec::new();
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= starts.len() {
                break done;
            }
            done.push((i, fit.run(&starts[i], opts)));
        }
    };
    let mut all: Vec<(usize, StartOutcome)> = if threads == 1 {
        work()
    } else {
        std::thread::scope(|s| {
            let handles: Vec<_> = (0..threads).map(|_| s.spawn(work)).collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().expect("identification worker panicked"))
                .collect()
        })
    };
    all.sort_by_key(|(i, _)| *i);
    all.into_iter().map(|(_, o)| o).collect()
}

/// `max / min - 1` of each parameter over the starts `good`.
fn parameter_spread(outcomes: &[StartOutcome], good: &[usize]) -> Vec<f64> {
    let Some(&first) = good.first() else {
        return Vec::new();
    };
    let values = |o: &StartOutcome| -> Vec<f64> {
        o.end
            .stiffness_nm_per_rad
            .iter()
            .chain(&o.end.damping_nms_per_rad)
            .copied()
            .collect()
    };
    let np = values(&outcomes[first]).len();
    (0..np)
        .map(|j| {
            let (lo, hi) = good
                .iter()
                .map(|&i| values(&outcomes[i])[j])
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                });
            hi / lo - 1.0
        })
        .collect()
}

/// The frequencies [Hz] of a batch of a pose's lines (the unused entries zero).
fn batch_hz(f_hz: &[f64], batch: &[(usize, Vec<Use>)]) -> [f64; LINES_PER_BATCH] {
    let mut f = [0.0; LINES_PER_BATCH];
    for (f, (k, _)) in f.iter_mut().zip(batch) {
        *f = f_hz[*k];
    }
    f
}

/// Where one cost term's line sits: the term and the line's position in it.
#[derive(Debug, Clone, Copy)]
struct Use {
    term: usize,
    j: usize,
}

/// The local fit of one worker: the plans of every pose, the cost's lines grouped by
/// pose and line (one FRF solve serves every element), the reweighting's weights, and the
/// buffers of the FRF and its derivatives.
struct Fit<'a> {
    cost: &'a Cost,
    poses: &'a [RigidPose],
    /// Per term and line: the sampled form's ratio to the continuous one [dB], zero for
    /// the continuous form.
    offset_db: Vec<Vec<f64>>,
    plans: Vec<FrfPlan>,
    /// Per pose: each line any term uses, with its uses.
    lines: Vec<Vec<(usize, Vec<Use>)>>,
    theta: Flexibilities,
    /// The majorisation's weight per term and line.
    w: Vec<Vec<f64>>,
    /// The error [dB] per term and line at the last cost pass.
    e: Vec<Vec<f64>>,
    /// The FRF of a batch of lines ([`LINES_PER_BATCH`] blocks of `N x N`).
    g: Vec<Complex64>,
    /// The pair rows and derivative factors of a batch of lines
    /// ([`FrfPlan::frf_and_pair_rows_lines_into`]).
    pair_rows: Vec<Complex64>,
    factors: Vec<Complex64>,
    /// One Jacobian row, and the rows gathered for `J^T J`.
    row: Vec<f64>,
    block: jacobian_block::JacobianBlock,
    /// The local fit's buffers.
    lm: reweighted_lm::LmBuffers,
    /// Whether the plans keep every batch's solve at the current `theta` and `e` holds its
    /// errors (the last error pass was at `theta` and complete, and neither `theta` nor
    /// the sampled form's ratio changed since): the normal equations then take up those
    /// solves ([`FrfPlan::frf_and_pair_rows_lines_kept_into`]) and errors.
    kept: bool,
}

impl<'a> Fit<'a> {
    fn new(poses: &'a [RigidPose], cost: &'a Cost) -> Self {
        let plans: Vec<FrfPlan> = poses.iter().map(FrfPlan::new).collect();
        let mut lines: Vec<Vec<(usize, Vec<Use>)>> = cost
            .f_hz
            .iter()
            .map(|f| (0..f.len()).map(|k| (k, Vec::new())).collect())
            .collect();
        for (term, t) in cost.terms.iter().enumerate() {
            for (j, &k) in t.lines.iter().enumerate() {
                lines[t.pose][k].1.push(Use { term, j });
            }
        }
        for l in &mut lines {
            l.retain(|(_, uses)| !uses.is_empty());
        }
        let pairs = plans.first().map_or(0, |p| p.pairs());
        let axes = cost.axes;
        Fit {
            cost,
            poses,
            offset_db: cost
                .terms
                .iter()
                .map(|t| vec![0.0; t.lines.len()])
                .collect(),
            plans,
            lines,
            theta: Flexibilities {
                stiffness_nm_per_rad: vec![1.0; pairs],
                damping_nms_per_rad: vec![1.0; pairs],
            },
            w: cost
                .terms
                .iter()
                .map(|t| vec![0.0; t.lines.len()])
                .collect(),
            e: cost
                .terms
                .iter()
                .map(|t| vec![0.0; t.lines.len()])
                .collect(),
            g: vec![Complex64::new(0.0, 0.0); LINES_PER_BATCH * axes * axes],
            pair_rows: vec![Complex64::new(0.0, 0.0); LINES_PER_BATCH * pairs * axes],
            factors: vec![Complex64::new(0.0, 0.0); LINES_PER_BATCH * 2 * pairs],
            row: vec![0.0; 2 * pairs],
            block: jacobian_block::JacobianBlock::new(2 * pairs),
            lm: reweighted_lm::LmBuffers::default(),
            kept: false,
        }
    }

    /// One start: Levenberg-Marquardt on `V` ([`reweighted_lm`]); in the sampled form,
    /// rounds of it with the sampled ratio refreshed between them until `V` stops falling.
    fn run(&mut self, start: &[f64], opts: &IdentifyOptions) -> StartOutcome {
        let start_theta = Flexibilities::from_log(start);
        let mut theta = start.to_vec();
        let mut evaluations = 0;
        let failed = |why: String, evaluations| StartOutcome {
            start: start_theta.clone(),
            end: start_theta.clone(),
            cost: f64::INFINITY,
            evaluations,
            failure: Some(why),
        };
        self.set_theta(&theta);
        if self.refresh_form(opts.form).is_none() {
            return failed("the sampled model is singular at the start".into(), 1);
        }
        let Some(mut v) = self.errors() else {
            return failed("the model is singular at the start".into(), 1);
        };
        evaluations += 1;
        let mut round_start = theta.clone();
        for round in 0..opts.rounds.max(1) {
            let v_round = v;
            let Some(d) = self.descend(&mut theta, v, opts.evals_per_round.max(2)) else {
                if round == 0 {
                    return failed(
                        "the model's derivatives are not finite at the start".into(),
                        1,
                    );
                }
                break;
            };
            evaluations += d.evaluations;
            let FrfForm::Sampled { .. } = opts.form else {
                v = d.v;
                break;
            };
            // the sampled form's ratio at the new parameters, for the next round (and V in
            // the sampled form)
            self.set_theta(&theta);
            let v_new = self.refresh_form(opts.form).and_then(|_| self.errors());
            evaluations += 1;
            match v_new {
                // a fall below the round-off of V ends it
                Some(v_new) if v_new < v_round * (1.0 - 1e-9) => v = v_new,
                Some(v_new) if v_new < v_round => {
                    v = v_new;
                    break;
                }
                _ => {
                    theta.copy_from_slice(&round_start);
                    break;
                }
            }
            round_start.copy_from_slice(&theta);
        }
        StartOutcome {
            start: start_theta,
            end: Flexibilities::from_log(&theta),
            cost: v,
            evaluations,
            failure: None,
        }
    }

    /// The errors [dB] at the current `theta` into `e`; `None` when the model is singular
    /// on a line.
    fn error_pass(&mut self) -> Option<()> {
        let nn = self.cost.axes * self.cost.axes;
        self.kept = false;
        for (pose, lines) in self.lines.iter().enumerate() {
            for (bi, batch) in lines.chunks(LINES_PER_BATCH).enumerate() {
                let f = batch_hz(&self.cost.f_hz[pose], batch);
                self.plans[pose]
                    .frf_lines_keep_into(bi, &f[..batch.len()], &self.theta, &mut self.g)
                    .ok()?;
                for ((_, uses), g) in batch.iter().zip(self.g.chunks_exact(nn)) {
                    for u in uses {
                        let t = &self.cost.terms[u.term];
                        self.e[u.term][u.j] = db_of(g[t.n * self.cost.axes + t.m])
                            + self.offset_db[u.term][u.j]
                            - t.measured_db[u.j];
                    }
                }
            }
        }
        self.kept = true;
        Some(())
    }

    /// The errors at the current `theta` into `e`, and `V`; `None` when the model is
    /// singular on a line.
    fn errors(&mut self) -> Option<f64> {
        self.error_pass()?;
        let v: f64 = self
            .cost
            .terms
            .iter()
            .zip(&self.e)
            .map(|(t, e)| self.cost.term_value(t, e.iter().copied()))
            .sum();
        v.is_finite().then_some(v)
    }

    /// The sampled form's ratio to the continuous model at the current `theta`, per term
    /// and line, into `offset_db`; `None` when either model is singular on a line.
    fn refresh_form(&mut self, form: FrfForm) -> Option<()> {
        let FrfForm::Sampled { fs_hz } = form else {
            return Some(());
        };
        // the errors kept are the former ratio's
        self.kept = false;
        for (pose, lines) in self.lines.iter().enumerate() {
            let sampled = SampledPose::new(&self.poses[pose], &self.theta, fs_hz).ok()?;
            for (k, uses) in lines {
                let f = self.cost.f_hz[pose][*k];
                self.plans[pose]
                    .frf_into(f, &self.theta, &mut self.g)
                    .ok()?;
                let gs = sampled.frf(f).ok()?;
                for u in uses {
                    let t = &self.cost.terms[u.term];
                    self.offset_db[u.term][u.j] =
                        db_of(gs[(t.n, t.m)]) - db_of(self.g[t.n * self.cost.axes + t.m]);
                }
            }
        }
        Some(())
    }

    /// The majorisation's weights at the errors of the last [`Fit::errors`].
    fn reweight(&mut self) {
        let p = self.cost.spec.p;
        for ((t, e), w) in self.cost.terms.iter().zip(&self.e).zip(&mut self.w) {
            let s: f64 = t
                .alpha
                .iter()
                .zip(e)
                .map(|(a, e)| a * abs_pow(*e, p))
                .sum::<f64>()
                / t.alpha_sum;
            let outer = s.max(1e-300).powf(1.0 / p - 1.0) / (2.0 * t.alpha_sum);
            for ((w, a), e) in w.iter_mut().zip(&t.alpha).zip(e) {
                // |E|^(p-2), floored for p < 2 where E = 0 (1e-6 dB: far below any noise)
                let inner = if p == 2.0 {
                    1.0
                } else {
                    e.abs().max(1e-6).powf(p - 2.0)
                };
                *w = a * inner * outer;
            }
        }
    }
}

impl NormalEquations for Fit<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    fn set_theta(&mut self, theta: &[f64]) {
        let s = self.theta.pairs();
        let mut same = true;
        let values = (self.theta.stiffness_nm_per_rad.iter_mut().zip(&theta[..s]))
            .chain(self.theta.damping_nms_per_rad.iter_mut().zip(&theta[s..]));
        for (x, t) in values {
            let v = t.exp();
            same &= v.to_bits() == x.to_bits();
            *x = v;
        }
        self.kept &= same;
    }

    fn cost(&mut self, _: &mut ()) -> Option<f64> {
        self.error_pass()?;
        let sum: f64 = self
            .w
            .iter()
            .zip(&self.e)
            .flat_map(|(w, e)| w.iter().zip(e).map(|(w, e)| w * e * e))
            .sum();
        sum.is_finite().then_some(sum)
    }

    fn normal_after_cost(&mut self, _: &mut (), jtj: &mut [f64], jtr: &mut [f64]) -> bool {
        let np = self.row.len();
        let npairs = np / 2;
        let axes = self.cost.axes;
        jtj.fill(0.0);
        jtr.fill(0.0);
        self.block.clear();
        let (nn, nr) = (axes * axes, npairs * axes);
        let kept = self.kept;
        for (pose, lines) in self.lines.iter().enumerate() {
            for (bi, batch) in lines.chunks(LINES_PER_BATCH).enumerate() {
                let f = &batch_hz(&self.cost.f_hz[pose], batch)[..batch.len()];
                let plan = &mut self.plans[pose];
                let (g, rows, factors) = (&mut self.g, &mut self.pair_rows, &mut self.factors);
                let solved = if kept {
                    plan.frf_and_pair_rows_lines_kept_into(bi, f, &self.theta, g, rows, factors)
                } else {
                    plan.frf_and_pair_rows_lines_into(f, &self.theta, g, rows, factors)
                };
                if solved.is_err() {
                    return false;
                }
                for (lane, (_, uses)) in batch.iter().enumerate() {
                    let g_line = &self.g[lane * nn..(lane + 1) * nn];
                    let rows = &self.pair_rows[lane * nr..(lane + 1) * nr];
                    let factors = &self.factors[lane * np..(lane + 1) * np];
                    for u in uses {
                        let t = &self.cost.terms[u.term];
                        let g = g_line[t.n * axes + t.m];
                        let sw = self.w[u.term][u.j].sqrt();
                        // the error pass's error where kept (the same expression of the
                        // same `g`: the same bits)
                        let e = if kept {
                            self.e[u.term][u.j]
                        } else {
                            db_of(g) + self.offset_db[u.term][u.j] - t.measured_db[u.j]
                        };
                        let r = sw * e;
                        // d(20 log10 |G|) = DB_PER_NEPER Re(dG / G), dG = factor a_n a_m
                        let scale = g.inv() * (sw * DB_PER_NEPER);
                        for (p, a) in rows.chunks_exact(axes).enumerate() {
                            let q = a[t.n] * a[t.m] * scale;
                            self.row[p] = (factors[p] * q).re;
                            self.row[npairs + p] = (factors[npairs + p] * q).re;
                        }
                        for (j, x) in jtr.iter_mut().zip(&self.row) {
                            *j += x * r;
                        }
                        self.block.push(&self.row, jtj);
                    }
                }
            }
        }
        self.block.flush(jtj);
        for a in 0..np {
            for b in 0..a {
                jtj[a * np + b] = jtj[b * np + a];
            }
        }
        jtj.iter().chain(jtr.iter()).all(|x| x.is_finite())
    }
}

mod jacobian_block;
mod reweighted_lm;
#[cfg(test)]
mod tests;

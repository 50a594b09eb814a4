//! Levenberg-Marquardt refinement of all `J`, `c`, `d` of an n-mass chain on the measured
//! FRF, with multi-start, standard deviations and automatic model order.
//!
//! * Parameters: `theta = ln(J1..Jn, c1..c(n-1), d1..d(n-1))`, positive by construction.
//! * Model: the exact ZOH-sampled response of the chain ([`crate::model::SampledChain`]),
//!   differenced velocity or position as the FRF says, with the known command delay.
//! * Residual per line: the complex log of `H_model/H_meas` (principal branch), real and
//!   imaginary parts each divided by `sigma_i = sqrt(var_i/2)/|H_meas,i|`, so that each has
//!   unit variance under the noise model. Lines with an infinite variance are dropped; lines
//!   with an unknown (zero) variance get the median sigma of the others.
//! * Jacobian: analytic, through the poles and residues of the chain (see
//!   `problem.rs`).
//! * Solver: an own Levenberg-Marquardt on the normal equations, accumulated while the
//!   residuals and Jacobian rows are computed (`lm.rs`; the `levenberg-marquardt` crate is
//!   the reference it is tested against).
//! * Multi-start: the given chain plus `starts - 1` log-normal perturbations of it, coarse
//!   to fine on long FRFs (see [`fit_chain`]).
//! * Covariance: `(J^T J)^-1 max(1, chi2/dof)`; standard deviations of the physical
//!   parameters by the delta method, `sigma_p = p sigma_theta`.

pub use super::budget::{BudgetSnapshot, FitBudget, NOT_TRIED};
pub use super::chain_fit::{ChainFit, ChainStd};
use super::error::IdentifyError;
use super::lines::{fallback_sigma, sample_rate, sigma_log, usable_lines, RigidReference};
use super::problem::{chain_of_theta, ChainProblem, FitData};
use crate::frf::{Frf, FrfKind};
use crate::lsq::lm::{self, Damping, LmOptions, LmWorkspace};
use crate::model::Chain;
use levenberg_marquardt::LeastSquaresProblem;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Options of [`fit_chain`] and [`select_order`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Number of starts: the initial chain plus `starts - 1` random perturbations (>= 1).
    pub starts: usize,
    /// Seed of the perturbations (the fit is deterministic for a given seed).
    pub seed: u64,
    /// Whole samples of command delay in the measurement.
    pub delay_samples: u32,
    /// Maximum number of residual evaluations per start.
    pub max_iter: usize,
    /// Only lines inside this band [Hz] (inclusive) are fitted; all lines when `None`.
    pub band_hz: Option<[f64; 2]>,
    /// Standard deviation of the log-normal perturbation of `J` and `c` in the random
    /// starts (0.3 = about +-30 %).
    pub spread: f64,
    /// Width in decades of the log-uniform spread of the dampings in the random starts.
    pub damping_decades: f64,
    /// Worker threads for the starts (1 = on the calling thread; 0 = the available
    /// parallelism, at most 4). The result does not depend on it.
    pub threads: usize,
    /// Time cap and progress counters (unlimited by default; see [`FitBudget`]).
    #[serde(skip)]
    pub budget: FitBudget,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            starts: 60,
            seed: 1,
            delay_samples: 0,
            max_iter: 400,
            band_hz: None,
            spread: 0.3,
            damping_decades: 1.0,
            threads: 0,
            budget: FitBudget::default(),
        }
    }
}

/// Fit all parameters of a chain of `init.masses()` bodies to `frf`, starting from `init`
/// (typically the exact inverse of the detected anti-resonance/resonance pairs) and
/// `opts.starts - 1` random perturbations of it.
///
/// Coarse to fine: with many lines (at least `2 COARSE_LINES`), every start first runs on
/// every `k`-th line only (about `COARSE_LINES` lines, loose tolerances), in waves of `WAVE`
/// starts after the first; a start that enters the basin of a coarse optimum of an earlier
/// wave stops and counts for it, and one that converges to an optimum more than `HOPELESS`
/// times worse than the best known is abandoned (see `run_coarse`); starts that reach
/// the same coarse optimum (all log-parameters within `SAME_OPTIMUM`) are one candidate,
/// candidates whose coarse cost is more than `HOPELESS` times the best are dropped, and
/// only the remaining candidates are refined on all lines with the full tolerances. The
/// refined optimum is the optimum of the full problem (the coarse phase only chooses where
/// the full solver starts); `starts_converged` counts the starts behind the candidates
/// that reached the best full cost.
pub fn fit_chain(frf: &Frf, init: &Chain, opts: &FitOptions) -> Result<ChainFit, IdentifyError> {
    fit_chain_coarse(frf, init, opts, COARSE_LINES)
}

/// [`fit_chain`] with `coarse_lines` lines in the coarse phase (`usize::MAX`: no coarse
/// phase, every start runs on all lines).
pub(super) fn fit_chain_coarse(
    frf: &Frf,
    init: &Chain,
    opts: &FitOptions,
    coarse_lines: usize,
) -> Result<ChainFit, IdentifyError> {
    init.validate()?;
    let data = prepare(frf, init.masses(), opts)?;
    let theta0 = theta_of(init);
    let starts = make_starts(&theta0, init.masses(), opts);
    let threads = worker_threads(opts, starts.len());
    let full_lm = lm_options(opts, data.params(), false);
    let stride = data.z.len() / coarse_lines.max(1);
    let mut last_err = String::from("no start");
    let mut total = 0;
    // (result on all lines, number of starts it stands for)
    let mut finals: Vec<(StartRun, usize)> = Vec::new();
    if stride >= 2 {
        let coarse = data.decimated(stride);
        let coarse_lm = lm_options(opts, data.params(), true);
        // waves: the first start alone, then WAVE at a time, each seeing the coarse optima
        // of the earlier waves
        let gate = opts.budget.gate(true);
        let mut first: Vec<Result<StartRun, String>> = Vec::with_capacity(starts.len());
        let mut known: Vec<(Vec<f64>, f64)> = Vec::new();
        let mut next = 0;
        while next < starts.len() {
            let wave = if next == 0 {
                1
            } else {
                WAVE.min(starts.len() - next)
            };
            let out = par_map(&starts[next..next + wave], threads, |t| {
                gate.run(|| run_coarse(&coarse, t.as_slice(), &coarse_lm, &known))
            });
            for r in out.iter().flatten() {
                if !r.abandoned && !known.iter().any(|k| same_optimum(&k.0, &r.theta)) {
                    known.push((r.theta.clone(), r.cost));
                }
            }
            first.extend(out);
            next += wave;
        }
        let mut ok: Vec<&StartRun> = Vec::with_capacity(first.len());
        for r in &first {
            match r {
                Ok(r) => {
                    total += r.evals;
                    ok.push(r);
                }
                Err(e) => last_err.clone_from(e),
            }
        }
        ok.sort_by(|a, b| a.cost.total_cmp(&b.cost));
        let mut groups: Vec<(&StartRun, usize)> = Vec::new();
        if let Some(best) = ok.first().map(|r| r.cost) {
            for r in ok {
                if let Some(g) = groups
                    .iter_mut()
                    .find(|g| same_optimum(&g.0.theta, &r.theta))
                {
                    g.1 += 1;
                } else if r.cost <= HOPELESS * best {
                    groups.push((r, 1));
                }
            }
        }
        let gate = opts.budget.gate(false);
        let refined = par_map(&groups, threads, |g| {
            gate.run(|| run_one(&data, &g.0.theta, &full_lm))
        });
        for (r, g) in refined.into_iter().zip(&groups) {
            match r {
                Ok(mut r) => {
                    total += r.evals;
                    r.evals += g.0.evals;
                    finals.push((r, g.1));
                }
                Err(e) => last_err = e,
            }
        }
    } else {
        let gate = opts.budget.gate(true);
        for r in par_map(&starts, threads, |t| {
            gate.run(|| run_one(&data, t.as_slice(), &full_lm))
        }) {
            match r {
                Ok(r) => {
                    total += r.evals;
                    finals.push((r, 1));
                }
                Err(e) => last_err = e,
            }
        }
    }
    finals.sort_by(|a, b| a.0.cost.total_cmp(&b.0.cost));
    // The best start whose optimum can be summarised: a start that ran off to a degenerate
    // chain (a pole pair merging into a double pole, a parameter overflowing) has no finite
    // Jacobian there and is passed over for the next best.
    for (r, _) in &finals {
        let tol = r.cost * 1e-6 + 1e-9;
        let converged = finals
            .iter()
            .filter(|f| f.0.cost <= r.cost + tol)
            .map(|f| f.1)
            .sum();
        match summarize(&data, &r.theta, r.cost, r.evals, starts.len(), converged) {
            Ok(mut fit) => {
                fit.evaluations_total = total;
                return Ok(fit);
            }
            Err(e) => last_err = e.to_string(),
        }
    }
    Err(IdentifyError::FitFailed {
        masses: init.masses(),
        starts: starts.len(),
        reason: last_err,
    })
}

/// The coarse phase of [`fit_chain`] for one start, `init` itself: its optimum on every
/// `k`-th line (about `COARSE_LINES` lines, on all where there are fewer than twice as
/// many) with the coarse tolerances, and its cost there. Costs of different starts on the
/// same `frf` and options are comparable: a screen of many starts before multi-start fits.
pub fn coarse_fit(
    frf: &Frf,
    init: &Chain,
    opts: &FitOptions,
) -> Result<(Chain, f64), IdentifyError> {
    init.validate()?;
    let data = prepare(frf, init.masses(), opts)?;
    let stride = (data.z.len() / COARSE_LINES).max(1);
    let coarse = data.decimated(stride);
    let lm = lm_options(opts, data.params(), true);
    let r = run_one(&coarse, theta_of(init).as_slice(), &lm).map_err(|reason| {
        IdentifyError::FitFailed {
            masses: init.masses(),
            starts: 1,
            reason,
        }
    })?;
    Ok((chain_of_theta(&r.theta, init.masses()), r.cost))
}

/// The solver's options for `np` parameters: the full tolerances, or the coarse phase's
/// looser ones; `opts.max_iter` evaluations per start, in whole Jacobians.
fn lm_options(opts: &FitOptions, np: usize, coarse: bool) -> LmOptions {
    let (ftol, xtol, gtol) = if coarse {
        (1e-8, 1e-6, 1e-8)
    } else {
        (1e-10, 1e-8, 1e-10)
    };
    LmOptions {
        ftol,
        xtol,
        gtol,
        max_evals: opts.max_iter.div_ceil(np + 1).max(1) * (np + 1),
        damping: Damping::Nielsen,
    }
}

/// Lines of the coarse problem the starts of [`fit_chain`] first run on (when there are at
/// least twice as many).
const COARSE_LINES: usize = 250;
/// Coarse optima closer than this in every log-parameter are one candidate (0.1 %).
const SAME_OPTIMUM: f64 = 1e-3;
/// Coarse optima with more than this times the best coarse cost are not refined.
const HOPELESS: f64 = 4.0;

fn same_optimum(a: &[f64], b: &[f64]) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < SAME_OPTIMUM)
}

/// One candidate order of [`select_order`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OrderCandidate {
    /// Number of bodies.
    pub masses: usize,
    /// Number of parameters `3n - 2`.
    pub params: usize,
    /// Weighted cost `chi2` of the best fit (infinite when the fit failed).
    pub cost: f64,
    /// `chi2/dof`.
    pub chi2_per_dof: f64,
    /// Bayesian information criterion `chi2/s^2 + P ln(N)` with `N` the number of real
    /// residuals and `s^2 = max(1, chi2/dof)` of the largest model (lower is better).
    pub bic: f64,
    /// Why the fit failed, if it did.
    pub error: Option<String>,
}

/// Result of [`select_order`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OrderSelection {
    /// The chosen fit.
    pub fit: ChainFit,
    /// Every candidate with its cost and criterion, in the order given.
    pub candidates: Vec<OrderCandidate>,
}

/// Fit each candidate initial chain (one per model order) and pick the order with the
/// lowest Bayesian information criterion on the weighted cost.
///
/// The noise scale is taken from the largest model (`s^2 = max(1, chi2/dof)`), so that an
/// under-estimated line variance does not push towards ever higher orders. To fix the order,
/// call [`fit_chain`] with that order's chain instead.
pub fn select_order(
    frf: &Frf,
    candidates: &[Chain],
    opts: &FitOptions,
) -> Result<OrderSelection, IdentifyError> {
    select_confirmed_order(frf, candidates, opts, |_, _| None)
}

/// [`select_order`] where a fitted candidate also has to pass `confirm(k, fit)` (candidate
/// index, its best fit): `Some(reason)` takes it out of the choice, and its
/// [`OrderCandidate::error`] says why. Used to refuse a fit that moved an offered pair to
/// where no significant feature was seen (a further pair can always lower the cost a
/// little by fitting a run of noisy lines somewhere in thousands of them; the information
/// criterion alone does not know that the pair's position was free).
pub fn select_confirmed_order(
    frf: &Frf,
    candidates: &[Chain],
    opts: &FitOptions,
    confirm: impl Fn(usize, &ChainFit) -> Option<String>,
) -> Result<OrderSelection, IdentifyError> {
    if candidates.is_empty() {
        return Err(IdentifyError::InvalidArgument(
            "no candidate order given".into(),
        ));
    }
    let fits = super::budget::fit_each_order(candidates, &opts.budget, opts.starts, |c| {
        fit_chain(frf, c, opts)
    });
    let largest = fits
        .iter()
        .filter_map(|f| f.as_ref().ok())
        .max_by_key(|f| f.params);
    let Some(largest) = largest else {
        return Err(fits.into_iter().next().unwrap().unwrap_err());
    };
    let s2 = largest.chi2_per_dof.max(1.0);
    let n_res = (2 * largest.lines_used) as f64;
    let mut report = Vec::new();
    let mut best: Option<(f64, usize)> = None;
    for (k, (c, f)) in candidates.iter().zip(&fits).enumerate() {
        let params = 3 * c.masses() - 2;
        let cand = match f {
            Ok(f) => {
                let bic = f.cost / s2 + params as f64 * n_res.ln();
                let refused = confirm(k, f);
                if refused.is_none() && best.is_none_or(|b| bic < b.0) {
                    best = Some((bic, k));
                }
                OrderCandidate {
                    masses: c.masses(),
                    params,
                    cost: f.cost,
                    chi2_per_dof: f.chi2_per_dof,
                    bic,
                    error: refused,
                }
            }
            Err(e) => OrderCandidate {
                masses: c.masses(),
                params,
                cost: f64::INFINITY,
                chi2_per_dof: f64::INFINITY,
                bic: f64::INFINITY,
                error: Some(e.to_string()),
            },
        };
        report.push(cand);
    }
    let Some((_, k)) = best else {
        return Err(IdentifyError::InvalidArgument(format!(
            "no candidate order was confirmed: {}",
            report
                .iter()
                .filter_map(|c| c
                    .error
                    .as_ref()
                    .map(|e| format!("{} bodies: {e}", c.masses)))
                .collect::<Vec<_>>()
                .join("; ")
        )));
    };
    let fit = fits.into_iter().nth(k).unwrap().unwrap();
    Ok(OrderSelection {
        fit,
        candidates: report,
    })
}

/// The starts [`fit_chain`] runs for `init` and `opts`, as log-parameter vectors
/// `ln(J1..Jn, c1..c(n-1), d1..d(n-1))` (the first is `init` itself, dampings floored as in
/// the fit): for comparing other solvers on exactly the same problem.
pub fn start_parameters(init: &Chain, opts: &FitOptions) -> Result<Vec<Vec<f64>>, IdentifyError> {
    init.validate()?;
    let theta0 = theta_of(init);
    Ok(make_starts(&theta0, init.masses(), opts)
        .into_iter()
        .map(|t| t.as_slice().to_vec())
        .collect())
}

/// The weighted residual vector [`fit_chain`] minimises, at `chain`: per usable line `i`
/// (in `frf` order, inside `opts.band_hz`), `w_i Re ln(H_model/H_meas)` then
/// `w_i Im ln(H_model/H_meas)` (principal branch), `w_i = 1/sigma_i`. Its squared norm is
/// the fit's `cost`. For comparing other solvers on exactly the same problem.
pub fn weighted_residuals(
    frf: &Frf,
    chain: &Chain,
    opts: &FitOptions,
) -> Result<Vec<f64>, IdentifyError> {
    chain.validate()?;
    let data = prepare(frf, chain.masses(), opts)?;
    let problem = ChainProblem::new(&data, theta_of(chain));
    problem
        .residuals()
        .map(|r| r.as_slice().to_vec())
        .ok_or_else(|| IdentifyError::FitFailed {
            masses: chain.masses(),
            starts: 0,
            reason: "residuals not finite at the given chain".into(),
        })
}

/// Log-parameters of a chain; zero dampings are floored at a damping ratio of about 1e-4 so
/// that their logarithm exists.
pub(super) fn theta_of(chain: &Chain) -> DVector<f64> {
    let n = chain.masses();
    let mut t = Vec::with_capacity(3 * n - 2);
    t.extend(chain.inertia_kgm2.iter().map(|v| v.ln()));
    t.extend(chain.stiffness_nm_per_rad.iter().map(|v| v.ln()));
    for (i, &d) in chain.damping_nms_per_rad.iter().enumerate() {
        let (ja, jb) = (chain.inertia_kgm2[i], chain.inertia_kgm2[i + 1]);
        let crit = 2.0 * (chain.stiffness_nm_per_rad[i] * ja * jb / (ja + jb)).sqrt();
        t.push(d.max(1e-4 * crit).ln());
    }
    DVector::from_vec(t)
}

fn make_starts(theta0: &DVector<f64>, n: usize, opts: &FitOptions) -> Vec<DVector<f64>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(opts.seed);
    let normal = Normal::new(0.0, opts.spread.max(0.0)).expect("finite spread");
    let half = 0.5 * opts.damping_decades.max(0.0) * std::f64::consts::LN_10;
    let mut starts = vec![theta0.clone()];
    for _ in 1..opts.starts.max(1) {
        let mut t = theta0.clone();
        for (j, v) in t.iter_mut().enumerate() {
            if j < 2 * n - 1 {
                *v += normal.sample(&mut rng);
            } else if half > 0.0 {
                *v += rng.random_range(-half..half);
            }
        }
        starts.push(t);
    }
    starts
}

/// One start's optimum.
struct StartRun {
    cost: f64,
    theta: Vec<f64>,
    evals: usize,
    /// Abandoned on the way to an optimum hopelessly worse than the best one known.
    abandoned: bool,
}

/// Starts of the coarse phase run in waves of this many (after the first start alone), each
/// start seeing the optima of the earlier waves. Fixed, so that the result does not depend
/// on the number of threads.
const WAVE: usize = 4;
/// A coarse start within this of a known coarse optimum in every log-parameter (1 %) ...
const MERGE_RADIUS: f64 = 1e-2;
/// ... with a cost at most this much above its cost (relative; and not below it) is in its
/// basin, practically converged: it is counted for that optimum and stops.
const MERGE_COST: f64 = 1e-2;
/// A coarse start still above `HOPELESS` times the best known coarse optimum after at least
/// this many evaluations ...
const ABANDON_EVALS: usize = 10;
/// ... whose last accepted step reduced the cost by less than this (relative) is converging
/// to a worse optimum (at that rate it would not get within `HOPELESS` of the best in its
/// whole budget): it is abandoned.
const ABANDON_REDUCTION: f64 = 1e-3;

/// A start of the coarse phase: [`run_one`] that stops early against the `known` optima of
/// earlier starts (`(theta, cost)`): as soon as it is in the basin of one of them
/// (`MERGE_RADIUS`, `MERGE_COST`; it then reports that optimum), or when it is converging
/// to an optimum more than `HOPELESS` times worse than the best of them (`ABANDON_EVALS`,
/// `ABANDON_REDUCTION`; reported as abandoned).
fn run_coarse(
    data: &FitData,
    theta: &[f64],
    lm_opts: &LmOptions,
    known: &[(Vec<f64>, f64)],
) -> Result<StartRun, String> {
    let near = |t: &[f64], c: f64| {
        known.iter().position(|(kt, kc)| {
            c >= *kc
                && c <= kc * (1.0 + MERGE_COST)
                && kt.iter().zip(t).all(|(a, b)| (a - b).abs() < MERGE_RADIUS)
        })
    };
    let best = known.iter().map(|k| k.1).fold(f64::INFINITY, f64::min);
    let hopeless = |c: f64, prev: f64, evals: usize| {
        evals >= ABANDON_EVALS && c > HOPELESS * best && prev - c < ABANDON_REDUCTION * prev
    };
    let mut problem = ChainProblem::unset(data);
    let mut ws = LmWorkspace::new(&problem, data.params());
    let out = lm::minimize_until(
        &mut problem,
        theta,
        lm_opts,
        &mut ws,
        &|t, c, prev, evals| near(t, c).is_some() || hopeless(c, prev, evals),
    )?;
    if !out.cost.is_finite() {
        return Err("non-finite cost".into());
    }
    if out.stopped {
        if let Some(k) = near(&ws.theta, out.cost) {
            return Ok(StartRun {
                cost: known[k].1,
                theta: known[k].0.clone(),
                evals: out.evaluations,
                abandoned: false,
            });
        }
    }
    Ok(StartRun {
        cost: out.cost,
        theta: ws.theta,
        evals: out.evaluations,
        abandoned: out.stopped,
    })
}

fn run_one(data: &FitData, theta: &[f64], lm_opts: &LmOptions) -> Result<StartRun, String> {
    let mut problem = ChainProblem::unset(data);
    let mut ws = LmWorkspace::new(&problem, data.params());
    let out = lm::minimize(&mut problem, theta, lm_opts, &mut ws)?;
    if !out.cost.is_finite() {
        return Err("non-finite cost".into());
    }
    Ok(StartRun {
        cost: out.cost,
        theta: ws.theta,
        evals: out.evaluations,
        abandoned: false,
    })
}

fn worker_threads(opts: &FitOptions, jobs: usize) -> usize {
    let threads = if opts.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get().min(4))
    } else {
        opts.threads
    };
    threads.clamp(1, jobs.max(1))
}

/// `f` on every item, in order, on up to `threads` scoped threads.
fn par_map<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = threads.clamp(1, items.len().max(1));
    if threads == 1 {
        return items.iter().map(&f).collect();
    }
    let chunk = items.len().div_ceil(threads);
    let f = &f;
    std::thread::scope(|s| {
        let handles: Vec<_> = items
            .chunks(chunk)
            .map(|c| s.spawn(move || c.iter().map(f).collect::<Vec<_>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("fit worker panicked"))
            .collect()
    })
}

/// Lines, weights and the known measurement factor, prepared once.
pub(super) fn prepare(
    frf: &Frf,
    masses: usize,
    opts: &FitOptions,
) -> Result<FitData, IdentifyError> {
    let fs = sample_rate(frf)?;
    // checks the kind
    let _ = RigidReference::new(frf, opts.delay_samples)?;
    let idx = usable_lines(frf, opts.band_hz);
    if idx.is_empty() {
        return Err(IdentifyError::NoUsableLines {
            band_hz: opts.band_hz.unwrap_or([0.0, f64::INFINITY]),
            total: frf.len(),
        });
    }
    let params = 3 * masses - 2;
    let needed = params / 2 + 1;
    if idx.len() < needed {
        return Err(IdentifyError::TooFewLines {
            what: "chain fit",
            usable: idx.len(),
            needed,
        });
    }
    let ts = 1.0 / fs;
    let fb = fallback_sigma(frf, &idx);
    let mut data = FitData {
        fs_hz: fs,
        ts,
        masses,
        z: Vec::with_capacity(idx.len()),
        zm1: Vec::with_capacity(idx.len()),
        k: Vec::with_capacity(idx.len()),
        gamma: Vec::with_capacity(idx.len()),
        w: Vec::with_capacity(idx.len()),
    };
    for &i in &idx {
        let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * frf.freq_hz[i] * ts);
        let delay = z.powi(-(opts.delay_samples as i32));
        let zm1 = super::problem::expm1(Complex64::new(
            0.0,
            2.0 * std::f64::consts::PI * frf.freq_hz[i] * ts,
        ));
        let g = match frf.kind {
            FrfKind::Position => delay,
            _ => zm1 / (z * ts) * delay,
        };
        data.z.push(z);
        data.zm1.push(zm1);
        data.k.push(g / frf.h[i]);
        data.gamma.push(ts * ts * (z + 1.0) / (2.0 * zm1 * zm1));
        data.w.push(1.0 / sigma_log(frf, i, fb));
    }
    Ok(data)
}

/// The residuals' Jacobian by central differences in the log-parameters: the fallback at an
/// optimum where the analytic one overflows (a chain that ran off to a degenerate limit,
/// e.g. a spring tending to zero with a pole at the origin, where the residue derivatives
/// blow up although the response itself stays finite).
fn central_difference_jacobian(data: &FitData, theta: &DVector<f64>) -> Option<DMatrix<f64>> {
    let np = data.params();
    let mut cols = Vec::with_capacity(np);
    for j in 0..np {
        let h = 1e-6 * (1.0 + theta[j].abs());
        let mut tp = theta.clone();
        tp[j] += h;
        let mut tm = theta.clone();
        tm[j] -= h;
        let rp = ChainProblem::new(data, tp).residuals()?;
        let rm = ChainProblem::new(data, tm).residuals()?;
        cols.push((rp - rm) / (2.0 * h));
    }
    let jac = DMatrix::from_columns(&cols);
    jac.iter().all(|v| v.is_finite()).then_some(jac)
}

fn summarize(
    data: &FitData,
    theta: &[f64],
    cost: f64,
    evals: usize,
    starts: usize,
    converged: usize,
) -> Result<ChainFit, IdentifyError> {
    let n = data.masses;
    let np = data.params();
    let lines = data.z.len();
    let mut problem = ChainProblem::unset(data);
    problem.set_theta(theta);
    let mut jtj = vec![0.0; np * np];
    let mut jtr = vec![0.0; np];
    let jtj = match problem.normal_equations(&mut problem.scratch(), &mut jtj, &mut jtr) {
        Some(_) => DMatrix::from_row_slice(np, np, &jtj),
        None => {
            let theta = DVector::from_column_slice(theta);
            let jac = central_difference_jacobian(data, &theta).ok_or_else(|| {
                IdentifyError::FitFailed {
                    masses: n,
                    starts,
                    reason: "Jacobian not finite at the optimum".into(),
                }
            })?;
            jac.transpose() * &jac
        }
    };
    let dof = (2 * lines).saturating_sub(np);
    let chi2_per_dof = if dof > 0 { cost / dof as f64 } else { f64::NAN };
    let inv = invert_spd(&jtj);
    let infl = if chi2_per_dof.is_finite() {
        chi2_per_dof.max(1.0)
    } else {
        1.0
    };
    let cov = inv * infl;
    let chain = chain_of_theta(theta, n);
    let sd: Vec<f64> = (0..np)
        .map(|j| theta[j].exp() * cov[(j, j)].max(0.0).sqrt())
        .collect();
    let std = ChainStd {
        inertia_kgm2: sd[..n].to_vec(),
        stiffness_nm_per_rad: sd[n..2 * n - 1].to_vec(),
        damping_nms_per_rad: sd[2 * n - 1..].to_vec(),
    };
    let lr = problem.log_ratios().unwrap_or_default();
    let db = 20.0 / std::f64::consts::LN_10;
    let m = lr.len().max(1) as f64;
    let residual_rms_db = (lr.iter().map(|l| (db * l.re).powi(2)).sum::<f64>() / m).sqrt();
    let residual_rms_deg = (lr.iter().map(|l| l.im.to_degrees().powi(2)).sum::<f64>() / m).sqrt();
    Ok(ChainFit {
        chain,
        std,
        cov_log: cov.transpose().as_slice().to_vec(),
        cost,
        chi2_per_dof,
        params: np,
        lines_used: lines,
        starts,
        starts_converged: converged,
        iterations: evals,
        evaluations_total: evals,
        residual_rms_db,
        residual_rms_deg,
    })
}

/// Inverse of the information matrix `JᵀJ`: [`crate::lsq::covariance_of_information`]
/// (an undetermined direction gets a huge variance, never zero).
pub(super) fn invert_spd(a: &DMatrix<f64>) -> DMatrix<f64> {
    crate::lsq::covariance_of_information(a)
}

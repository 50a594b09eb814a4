//! Diagnosis of the sim-to-real gap: where the identified chain and the measurement part
//! ([`localise`]), what kind of residual it is ([`distortion`]), which unmodelled effect
//! explains it ([`effects`], ranked in [`rank`]) and how far the gap shrinks with it.
//!
//! [`diagnose`] takes one recording per excitation amplitude and the nominal number of
//! bodies; plain code, no I/O. The CLI is `flexid diagnose`. Non-periodic recordings of
//! one body (trajectories, often in closed loop) take the time-domain path of
//! [`trajectory`] instead: the rigid body with friction by inverse dynamics.

pub mod acceleration;
pub mod after_torque;
pub mod amplitude_mode;
pub mod damper_free;
pub mod distortion;
mod effect;
pub mod effects;
pub mod ground_spring;
pub mod json;
pub mod kept_outputs;
pub mod level_change;
pub mod localise;
pub mod loop_free;
pub mod lti;
pub mod modal;
pub mod nlsim;
pub mod noise;
pub mod rank;
mod renominal;
pub mod scan;
pub mod search;
pub mod select;
pub mod shortened;
pub mod simplex;
pub mod small_signal;
pub mod sweep_plan;
#[cfg(test)]
mod tests_support;
pub mod tone_deflection;
pub mod torque_path;
pub mod trajectory;

use crate::analysis::{
    analyze_estimate, estimate_frf, AnalysisError, AnalysisOptions, EstimatedFrf,
};
use crate::frf::{FrfKind, NonExcitedLevels};
use crate::identify::fit::FitBudget;
use crate::recording::Recording;
use distortion::{LevelChange, LevelDistortion};
pub use effect::Effect;
use effects::{EffectFit, Lin, Target};
use localise::Band;
use lti::LinExt;
use num_complex::Complex64;

/// The candidate effects' wire names, in the order they are reported when tied (see
/// [`Effect::ALL`]).
pub const EFFECTS: [&str; 8] = {
    let mut names = [""; 8];
    let mut i = 0;
    while i < 8 {
        names[i] = Effect::ALL[i].name();
        i += 1;
    }
    names
};

/// Errors of [`diagnose`].
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    #[error("no recording given")]
    NoRecordings,
    #[error("recording {0}: {1}")]
    Analysis(usize, crate::analysis::AnalysisError),
    #[error("recording {0}: the response is neither a position, a velocity nor an acceleration")]
    Kind(usize),
    #[error("recording {0}: no nominal {1}-mass chain could be fitted")]
    NoNominal(usize, usize),
    #[error("the recordings have different sample rates")]
    Rates,
    #[error("recording {0} (trajectory path): {1}")]
    Trajectory(usize, trajectory::TrajectoryError),
    /// No line of a recording's FRF has a usable variance (one measured period, a constant
    /// torque): nothing to fit or to compare (issue 16: this panicked).
    #[error(
        "recording {index}: no excited line with a usable variance ({averages} period(s) or \
         segment(s) averaged; at least 2 measured periods after the transient and a varying \
         torque are needed)"
    )]
    NoUsableLines { index: usize, averages: usize },
    /// The time cap passed before the nominal chain could be fitted: nothing to diagnose
    /// from (the command line then identifies the nominal chain on its own).
    #[error("the time cap of {max_seconds} s passed after {elapsed_s:.2} s, before the nominal chain was fitted")]
    CappedBeforeNominal { max_seconds: f64, elapsed_s: f64 },
}

/// Options of [`diagnose`].
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Bodies of the nominal chain.
    pub masses: usize,
    /// Analysis band [Hz] (default: the excited band).
    pub band_hz: Option<[f64; 2]>,
    /// Sub-steps per sample of the time-domain simulation of amplitude-dependent effects,
    /// at most: never finer than [`FINEST_SUBSTEP_HZ`] ([`substeps_at`]).
    pub substeps: usize,
    /// Sub-steps per sample for the spring nonlinearities (backlash, hardening), at most
    /// (as `substeps`).
    pub spring_substeps: usize,
    /// Fit lines per level used by the joint linear refits (all lines are scored).
    pub fit_lines: usize,
    /// Run the amplitude-dependent candidates even without amplitude dependence/distortion.
    pub force_nonlinear: bool,
    /// The nominal model has a spring from its last body to the ground (the user's
    /// `--ground-spring`; [`ground_spring`]): its stiffness is a nominal parameter, and
    /// `gravity` is no candidate. Off (the default): a free chain, as before.
    pub ground_spring: bool,
    /// The calling thread's CPU clock [ns] for [`Diagnosis::stage_cpu_s`] (for example
    /// `flexid_rt::clock::thread_cpu_ns`); `None` (the default) leaves the stages empty.
    /// The core reads no clock of its own: its results depend on the input only.
    pub cpu_clock: Option<fn() -> Option<u64>>,
    /// The time cap (`flexid diagnose --max-seconds`; unlimited by default), checked
    /// between the steps of the diagnosis: the nominal fit's starts, each candidate
    /// effect's fit, each step of the forward selection, the mode search. Once it has
    /// passed, no further candidate is tried and the diagnosis is made from what was
    /// fitted, marked in [`Diagnosis::time_cap`]. The identifications behind the nominal
    /// starts run under it too (each ends with the best of the starts it did).
    pub budget: FitBudget,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            masses: 2,
            band_hz: None,
            substeps: 4,
            spring_substeps: 4,
            fit_lines: 300,
            force_nonlinear: false,
            ground_spring: false,
            cpu_clock: None,
            budget: FitBudget::unlimited(),
        }
    }
}

/// One recording's measured FRF.
#[derive(Debug, Clone)]
pub struct Level {
    pub f: Vec<f64>,
    pub h: Vec<Complex64>,
    pub var: Vec<f64>,
    /// Indices of these lines in the estimator's output (to match simulated estimates).
    pub keep: Vec<usize>,
    pub nonexcited: Option<NonExcitedLevels>,
    pub rec: Recording,
    pub torque_rms: f64,
    pub io_delay: u32,
    /// Periods (periodic) or segments (Welch) averaged: the line variances' degrees of
    /// freedom (see [`noise`]).
    pub averages: usize,
    /// Several realisations of a multisine: `var` is the noise alone, this the variance
    /// from the spread over the realisations (noise and stochastic nonlinear distortion),
    /// on the same lines. `None` otherwise.
    pub spread_var: Option<Vec<f64>>,
    /// `rec` cut for the search's short simulations of a stepped sine, once per number of
    /// steady periods.
    pub shortened: shortened::ShortenedCuts,
    /// The recording's sweep estimator planned for the search's simulations.
    pub sweep_plan: sweep_plan::SweepPlan,
    /// The FRF of `rec` as [`estimate_frf`] gave it to [`prepare`] (before the realisations'
    /// variances were swapped), and the band it was asked for: the nominal starts identify
    /// from it instead of estimating it again ([`Level::measured`]). `None`: estimate anew.
    pub measured: Option<(Option<[f64; 2]>, std::sync::Arc<EstimatedFrf>)>,
}

impl Level {
    /// `estimate_frf(&self.rec, band)`: the estimate [`prepare`] made when `band` is the
    /// one it was made for (the same to the bit), else a new one.
    pub fn measured(&self, band: Option<[f64; 2]>) -> Result<EstimatedFrf, AnalysisError> {
        match &self.measured {
            Some((b, e)) if *b == band => Ok(e.as_ref().clone()),
            _ => estimate_frf(&self.rec, band),
        }
    }
}

/// The measurements as the effect fits see them.
#[derive(Debug, Clone)]
pub struct Data {
    pub levels: Vec<Level>,
    pub fs: f64,
    pub kind: FrfKind,
    pub band: Option<[f64; 2]>,
    pub substeps: usize,
    pub spring_substeps: usize,
    /// Decimated lines per level (joint refits).
    pub targets: Vec<Target>,
    /// All lines per level.
    pub full_targets: Vec<Target>,
    /// What noise alone gives as reduced chi² (mean and significance threshold).
    pub noise: noise::NoiseChi2,
    /// The drive's torque reading against its command, where every recording has one
    /// ([`torque_path`]): on which side of the torque a lag sits.
    pub torque: Option<torque_path::TorquePath>,
}

impl Data {
    /// chi² of a model (per level, all lines).
    pub fn chi2(&self, model: &[Vec<Complex64>]) -> f64 {
        self.levels
            .iter()
            .zip(model)
            .map(|(l, m)| localise::z2(&l.h, &l.var, m).iter().sum::<f64>())
            .sum()
    }
    /// chi² of a linear model (chain and extensions) on all lines of every level.
    pub fn chi2_of(&self, lin: &LinExt) -> f64 {
        self.chi2(&effects::model_on(
            lin,
            self.fs,
            self.kind,
            &self.full_targets,
        ))
    }
    pub fn lines(&self) -> usize {
        self.levels.iter().map(|l| l.f.len()).sum()
    }
    /// Whether a model's chi² (all lines) is within the noise ([`noise`]).
    pub fn within_noise(&self, chi2: f64) -> bool {
        chi2 < self.noise.threshold * self.lines() as f64
    }
    pub fn f_min(&self) -> f64 {
        self.levels
            .iter()
            .map(|l| l.f[0])
            .fold(f64::INFINITY, f64::min)
    }
    pub fn f_max(&self) -> f64 {
        self.levels
            .iter()
            .map(|l| *l.f.last().unwrap())
            .fold(0.0, f64::max)
    }
    pub fn torque_rms_min(&self) -> f64 {
        self.levels
            .iter()
            .map(|l| l.torque_rms)
            .fold(f64::INFINITY, f64::min)
    }
    /// RMS deflection of coupling `k` of `lin` under the lowest (`low`) or highest level.
    pub fn deflection_rms(&self, lin: &LinExt, k: usize, low: bool) -> f64 {
        let l = self
            .levels
            .iter()
            .min_by(|a, b| {
                let o = a.torque_rms.total_cmp(&b.torque_rms);
                if low {
                    o
                } else {
                    o.reverse()
                }
            })
            .unwrap();
        let out = nlsim::simulate(lin, nlsim::Nl::None, &l.rec.torque_cmd_nm, self.fs, 1);
        out.defl_rms.get(k).copied().unwrap_or(0.0)
    }
}

fn target(l: &Level, max_lines: usize) -> Target {
    let n = l.f.len();
    let idx: Vec<usize> = if n <= max_lines {
        (0..n).collect()
    } else {
        // half log-spaced (the low end), half uniform
        let mut v: Vec<usize> = (0..max_lines / 2)
            .map(|i| {
                ((n as f64 - 1.0).powf(i as f64 / (max_lines / 2 - 1) as f64)).round() as usize
            })
            .chain((0..max_lines / 2).map(|i| i * (n - 1) / (max_lines / 2 - 1)))
            .collect();
        v.push(0);
        v.sort_unstable();
        v.dedup();
        v
    };
    target_on(l, idx)
}

/// The target of level `l`'s lines `idx`: their frequencies, responses and weights
/// `|H| / sigma`.
pub(crate) fn target_on(l: &Level, idx: Vec<usize>) -> Target {
    Target {
        f: idx.iter().map(|&i| l.f[i]).collect(),
        h: idx.iter().map(|&i| l.h[i]).collect(),
        w: idx
            .iter()
            .map(|&i| l.h[i].norm() / l.var[i].sqrt())
            .collect(),
        io_delay: l.io_delay,
        band_limited: l
            .rec
            .sidecar
            .excitation
            .as_ref()
            .is_some_and(|e| e.band_limited),
        idx,
    }
}

/// Build [`Data`] from recordings (measured FRFs on the excited lines in band).
pub fn prepare(recs: &[Recording], opts: &DiagnoseOptions) -> Result<Data, DiagnoseError> {
    if recs.is_empty() {
        return Err(DiagnoseError::NoRecordings);
    }
    let fs = recs[0].sample_rate_hz;
    let mut levels = Vec::new();
    let mut kind = FrfKind::DifferencedVelocity;
    for (i, r) in recs.iter().enumerate() {
        if (r.sample_rate_hz - fs).abs() > 1e-9 * fs {
            return Err(DiagnoseError::Rates);
        }
        let mut e = estimate_frf(r, opts.band_hz).map_err(|e| DiagnoseError::Analysis(i, e))?;
        let measured = Some((opts.band_hz, std::sync::Arc::new(e.clone())));
        kind = e.frf.kind;
        if kind == FrfKind::Other {
            return Err(DiagnoseError::Kind(i));
        }
        // several realisations of a multisine: the models are judged against the noise
        // alone (the spread over realisations holds the stochastic nonlinear distortion,
        // which the simulated candidates reproduce and a linear model cannot: it is part
        // of the gap)
        let mut spread = None;
        if let Some((v, periods)) = e.noise_var.take() {
            spread = Some(std::mem::replace(&mut e.frf.var, v));
            e.averages = periods;
        }
        // the lines that carry information ([`crate::frf::supported_band`]): beyond the
        // band where the response stands out of its own scatter a line holds noise, whose
        // gap says nothing about the model (and whose variance, where an encoder's counts
        // dominate, is the least certain)
        let supported = crate::frf::supported_band(&e.frf).map(|s| s.band_hz);
        let keep: Vec<usize> = e
            .frf
            .usable_lines()
            .into_iter()
            .filter(|&k| {
                let f = e.frf.freq_hz[k];
                supported.is_none_or(|[lo, hi]| f >= lo && f <= hi)
            })
            .collect();
        if keep.is_empty() {
            return Err(DiagnoseError::NoUsableLines {
                index: i,
                averages: e.averages,
            });
        }
        let n = r.torque_cmd_nm.len().max(1) as f64;
        let mean = r.torque_cmd_nm.iter().sum::<f64>() / n;
        let rms = (r
            .torque_cmd_nm
            .iter()
            .map(|t| (t - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let spread_var = spread.map(|s| keep.iter().map(|&k| s[k]).collect());
        levels.push(Level {
            f: keep.iter().map(|&k| e.frf.freq_hz[k]).collect(),
            h: keep.iter().map(|&k| e.frf.h[k]).collect(),
            var: keep.iter().map(|&k| e.frf.var[k]).collect(),
            keep,
            nonexcited: e.nonexcited,
            rec: r.clone(),
            torque_rms: rms,
            io_delay: r.sidecar.io_delay_samples.unwrap_or(0),
            averages: e.averages,
            spread_var,
            shortened: Default::default(),
            sweep_plan: Default::default(),
            measured,
        });
    }
    let targets = levels.iter().map(|l| target(l, opts.fit_lines)).collect();
    let full_targets = levels.iter().map(|l| target(l, usize::MAX)).collect();
    let noise = noise::reduced_chi2(
        &levels
            .iter()
            .map(|l| (l.f.len(), l.averages))
            .collect::<Vec<_>>(),
    );
    Ok(Data {
        noise,
        torque: torque_path::TorquePath::measure(recs, opts.band_hz),
        levels,
        fs,
        kind,
        band: opts.band_hz,
        substeps: substeps_at(opts.substeps, fs),
        spring_substeps: substeps_at(opts.spring_substeps, fs),
        targets,
        full_targets,
    })
}

/// The finest sub-step rate of the effects' simulation [Hz]: the default 4 sub-steps per
/// sample at 2 kHz. The sub-steps hold the effect's torque while the chain moves (the
/// linear part is exact, ZOH, at any step), so their error is set by the chain's
/// frequencies against the sub-step's length, not by the sample rate: at 4 kHz, 4
/// sub-steps a sample were twice the resolution the same chain had at 2 kHz, and 4 kHz
/// stepped sines were the slowest diagnoses (the time loop 75 % of them).
pub const FINEST_SUBSTEP_HZ: f64 = 8000.0;

/// Sub-steps per sample at `fs` [Hz]: `per_sample` at most, and no finer than
/// [`FINEST_SUBSTEP_HZ`] (at least one).
pub fn substeps_at(per_sample: usize, fs: f64) -> usize {
    let finest = (FINEST_SUBSTEP_HZ / fs).ceil();
    if finest.is_finite() && finest >= 1.0 {
        per_sample.min(finest as usize).max(1)
    } else {
        per_sample.max(1)
    }
}

/// The gap in numbers.
#[derive(Debug, Clone)]
pub struct Gap {
    /// Systematic RMS log-complex gap over all lines of all levels [dB], nominal model
    /// (inverse-variance weighted, noise removed; see [`rms_parts`]).
    pub before_rms_db: f64,
    /// Plain RMS of the log-complex gap (noise included), before and after [dB].
    pub before_raw_rms_db: f64,
    pub after_raw_rms_db: f64,
    /// The same with the winning effect (equal to before when the verdict is `none`).
    pub after_rms_db: f64,
    /// Magnitude-only and phase-only RMS, before and after [dB, deg].
    pub before_mag_db: f64,
    pub after_mag_db: f64,
    pub before_phase_deg: f64,
    pub after_phase_deg: f64,
    /// RMS of the noise alone (one-sigma of the line estimates) [dB].
    pub noise_rms_db: f64,
    /// Localised bands (nominal model), with the gap after in each.
    pub bands: Vec<(Band, f64)>,
}

/// What the residual is made of.
#[derive(Debug, Clone)]
pub struct ResidualKind {
    /// Reduced chi² of the nominal model (1 = within noise).
    pub reduced_chi2: f64,
    /// Within the noise over the whole band ([`Data::within_noise`]).
    pub within_noise: bool,
    /// The FRF changes between two levels beyond both variances, over the whole band or on
    /// a run of lines ([`distortion::level_change`], [`scan`]): amplitude dependence, which
    /// no linear model has (a nominal chain fitted to every level at once cannot be right
    /// for each), so the gap is real wherever the chi² over the band says.
    pub changed: bool,
    pub nonlinear: bool,
    pub linear_model_error: bool,
    /// The most significant run of lines of the nominal model's gap ([`scan`]; its
    /// `series` is the level).
    pub local: Option<Located>,
    /// The most significant run of lines of the FRF's change between two levels.
    pub change_local: Option<Located>,
    pub levels: Vec<LevelDistortion>,
    pub changes: Vec<LevelChange>,
}

impl ResidualKind {
    /// Whether the gap is more than noise: the nominal model's chi² over the band beyond
    /// the noise's threshold. A significant change between levels ([`ResidualKind::changed`])
    /// would be evidence too, in principle (no linear model has it), but it rests on every
    /// line's variance being right, and on coarse encoders and sweeps they are not yet:
    /// tried, it named a hardening spring to the ground the band's chi² had missed and called
    /// eight cases without effect `unexplained` at gaps of 0.00-0.11 dB (world benchmark,
    /// development seeds; see the changelog).
    pub fn gap_is_real(&self) -> bool {
        !self.within_noise
    }
}

/// A scan's most significant window, with the pair of levels it compares (for the
/// change between levels).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Located {
    #[serde(flatten)]
    pub window: scan::Window,
    pub pair: Option<(usize, usize)>,
}

impl From<scan::Window> for Located {
    fn from(window: scan::Window) -> Self {
        Located { window, pair: None }
    }
}

/// One effect named by the forward selection, with the gap once it and every effect
/// before it are modelled.
#[derive(Debug, Clone)]
pub struct Step {
    pub effect: Effect,
    /// The fit of the whole set up to this step (the chain, this effect and the ones before).
    pub fit: EffectFit,
    /// Systematic RMS gap with the set up to this step [dB] (see [`rms_parts`]).
    pub after_rms_db: f64,
    /// chi² reduction over the step before minus the BIC price of the parameters added.
    pub score: f64,
}

/// The whole diagnosis.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// The strongest effect named (the first of [`Diagnosis::effects`]), `none` or
    /// `unexplained`.
    pub verdict: Effect,
    /// Every effect named, strongest first (empty for `none` and `unexplained`).
    pub effects: Vec<Step>,
    pub masses: usize,
    pub nominal: EffectFit,
    /// Candidates ranked (best first), with scores.
    pub ranking: Vec<rank::Ranked>,
    /// The fit of the verdict's effect alone (the first of [`Diagnosis::effects`]).
    pub winner: Option<EffectFit>,
    /// The gap before, and after with every effect named (the last step's model).
    pub gap: Gap,
    pub residual: ResidualKind,
    pub data: Data,
    pub notes: Vec<String>,
    pub seconds: f64,
    /// CPU time of the diagnosing thread per stage [s], in order: `prepare` (the measured
    /// FRFs), `nominal` (identification and joint fit), `residual`, each candidate fitted
    /// (by effect name), `select` (ranking and forward selection), `rank` (the verdict and the gap). Empty where the thread's CPU time is not
    /// available.
    pub stage_cpu_s: Vec<(&'static str, f64)>,
    /// The time-domain identification when the trajectory path was taken (a non-periodic
    /// recording and one body, [`trajectory::diagnosis::applies`]): the rigid body with
    /// friction by IDIM-LS, its cut-off, samples, noise and cross-tests. The other fields
    /// then hold its verdict, gap (force residuals) and ranking, and no FRF (`data.levels`
    /// is empty). `None` on the frequency-domain path.
    pub trajectory: Option<trajectory::TrajectoryFit>,
    /// Whether the time cap ([`DiagnoseOptions::budget`]) stopped the diagnosis, and what
    /// it left out.
    pub time_cap: TimeCap,
    /// The modes of the band where the FRF changes between levels, fitted at each level
    /// and compared ([`amplitude_mode`]): made when no candidate explains a real gap and
    /// the FRF changes significantly between levels (`None` otherwise). The verdict is
    /// `amplitude_dependent_mode` when it names a change.
    pub amplitude_mode: Option<amplitude_mode::AmplitudeMode>,
}

/// The time cap of a diagnosis: whether it was reached and which steps were not tried
/// (candidate effects by name, `forward selection step N`, the damper-free start, ...).
/// A capped diagnosis's verdict, ranking and gap come from the steps that were done.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TimeCap {
    /// The cap [s] (`None`: unlimited).
    pub max_seconds: Option<f64>,
    /// Whether the cap stopped anything (a step not tried, or a start of an identification
    /// skipped).
    pub capped: bool,
    /// Seconds from the start of the diagnosis (of its budget) to its answer.
    pub elapsed_s: f64,
    /// The steps not tried because the cap had passed, in the order they were skipped.
    pub not_tried: Vec<String>,
}

impl TimeCap {
    /// The state of `budget` now, with the steps skipped.
    pub fn of(budget: &FitBudget, not_tried: Vec<String>) -> Self {
        let s = budget.snapshot();
        TimeCap {
            max_seconds: s.max_seconds,
            capped: s.capped || !not_tried.is_empty(),
            elapsed_s: s.elapsed_s,
            not_tried,
        }
    }
    /// What the cap left out, in words (for the notes and the report).
    pub fn words(&self) -> String {
        format!(
            "TIME CAP: {} s reached after {:.2} s; the verdict is made from what was fitted (not tried: {})",
            self.max_seconds.unwrap_or(f64::INFINITY),
            self.elapsed_s,
            if self.not_tried.is_empty() {
                "some starts of the nominal identification or the mode search".to_string()
            } else {
                self.not_tried.join(", ")
            }
        )
    }
}

/// The steps of one diagnosis under its time cap: [`Steps::go`] says whether a step may
/// start, and remembers those that may not.
struct Steps {
    budget: FitBudget,
    not_tried: Vec<String>,
}

impl Steps {
    fn new(budget: &FitBudget) -> Self {
        Steps {
            budget: budget.clone(),
            not_tried: Vec::new(),
        }
    }

    /// Whether `step` may run: false (and `step` is listed as not tried) once the cap has
    /// passed.
    fn go(&mut self, step: impl std::fmt::Display) -> bool {
        if self.budget.expired() {
            self.not_tried.push(step.to_string());
            false
        } else {
            true
        }
    }
}

/// Per-stage CPU time of the calling thread (see [`Diagnosis::stage_cpu_s`]), read from
/// the caller's clock ([`DiagnoseOptions::cpu_clock`]).
struct StageClock {
    clock: fn() -> Option<u64>,
    last: Option<u64>,
    stages: Vec<(&'static str, f64)>,
}

impl StageClock {
    fn start(clock: Option<fn() -> Option<u64>>) -> Self {
        let clock = clock.unwrap_or(|| None);
        StageClock {
            clock,
            last: clock(),
            stages: Vec::new(),
        }
    }

    /// Close the stage `name` (the CPU time since the previous one).
    fn lap(&mut self, name: &'static str) {
        let now = (self.clock)();
        if let (Some(a), Some(b)) = (self.last, now) {
            self.stages.push((name, b.saturating_sub(a) as f64 * 1e-9));
        }
        self.last = now;
    }
}

/// The identification behind a nominal start: `masses` bodies in `band`, 8 starts on one
/// thread (the diagnosis runs on one core), under the diagnosis's time cap.
pub(crate) fn nominal_analysis(
    masses: usize,
    band: Option<[f64; 2]>,
    budget: &FitBudget,
) -> AnalysisOptions {
    AnalysisOptions {
        masses: Some(masses),
        band_hz: band,
        fit: crate::identify::fit::FitOptions {
            starts: 8,
            threads: 1,
            budget: budget.clone(),
            ..AnalysisOptions::default().fit
        },
        ..AnalysisOptions::default()
    }
}

fn nominal_start(
    level: &Level,
    masses: usize,
    band: Option<[f64; 2]>,
    budget: &FitBudget,
) -> Option<crate::model::Chain> {
    let opts = nominal_analysis(masses, band, budget);
    // `analyze(rec, opts)` from the level's estimate (the same band)
    let rec = &level.rec;
    let measured = level.measured(band).ok();
    let analysed = measured
        .clone()
        .and_then(|m| analyze_estimate(rec, m, &opts).ok());
    match analysed {
        Some(a) => a.fit.map(|f| f.chain),
        None if masses == 1 => {
            // a rigid body: its inertia from the low-frequency gain
            let a = measured.clone().and_then(|m| {
                analyze_estimate(
                    rec,
                    m,
                    &AnalysisOptions {
                        masses: None,
                        ..opts
                    },
                )
                .ok()
            });
            let j = a
                .as_ref()
                .and_then(|a| a.total_inertia.as_ref().map(|t| t.j_kgm2))
                .or_else(|| {
                    let e = measured?;
                    let k = e.frf.len().min(5).max(1);
                    let s: f64 = (0..k)
                        .map(|i| {
                            1.0 / (2.0
                                * std::f64::consts::PI
                                * e.frf.freq_hz[i]
                                * e.frf.h[i].norm())
                        })
                        .sum();
                    Some(s / k as f64)
                })?;
            crate::model::Chain::new(vec![j], vec![], vec![]).ok()
        }
        None => None,
    }
}

/// Diagnose the gap between the nominal `opts.masses`-body chain and the recordings (one per
/// excitation amplitude).
pub fn diagnose(recs: &[Recording], opts: &DiagnoseOptions) -> Result<Diagnosis, DiagnoseError> {
    let t0 = std::time::Instant::now();
    let mut stage = StageClock::start(opts.cpu_clock);
    if trajectory::diagnosis::applies(recs, opts.masses) {
        let mut d = trajectory::diagnosis::diagnose(recs, opts)?;
        stage.lap("trajectory");
        d.seconds = t0.elapsed().as_secs_f64();
        d.stage_cpu_s = stage.stages;
        return Ok(d);
    }
    // an acceleration or velocity response is diagnosed as the position it integrates to
    let recs: Vec<Recording> = recs.iter().map(acceleration::as_position).collect();
    let mut data = prepare(&recs, opts)?;
    // the chain behind the loop the drive's torque reading shows: a start of the
    // current-loop candidate ([`loop_free`])
    let loop_start = loop_free::start(&data, opts.masses.max(1), opts.band_hz, &opts.budget);
    if let Some(tp) = data.torque.as_mut() {
        tp.loop_free = loop_start;
    }
    stage.lap("prepare");
    let mut steps = Steps::new(&opts.budget);
    if !steps.go("nominal chain") {
        let s = opts.budget.snapshot();
        return Err(DiagnoseError::CappedBeforeNominal {
            max_seconds: s.max_seconds.unwrap_or(f64::INFINITY),
            elapsed_s: s.elapsed_s,
        });
    }
    let n = opts.masses.max(1);
    let mut idents = Vec::new();
    let (nom_lin, grounded_damped) = if opts.ground_spring {
        fit_grounded_nominal(&data, n, opts.band_hz, &opts.budget, &mut idents)?
    } else {
        (
            fit_nominal(&data, n, opts.band_hz, &opts.budget, &mut idents)?,
            None,
        )
    };
    // the chain identified with the motor's damper to the ground taken out of the
    // measurement: a start the damper's fit cannot reach from a free chain bent to mimic it
    // (not needed when the free chain already leaves only noise); with a ground spring, the
    // grounded fit with its damper instead (a free chain's start is none)
    let damper_free: Vec<LinExt> = if opts.ground_spring {
        grounded_damped.into_iter().collect()
    } else if data.within_noise(data.chi2_of(&nom_lin)) || !steps.go("damper-free nominal start") {
        Vec::new()
    } else {
        damper_free::start(&data, n, opts.band_hz, &opts.budget)
            .into_iter()
            .collect()
    };
    stage.lap("damper_free");
    // a candidate whose own parameter is not significant can be the nominal model fitted
    // better (its extension's path led the chain out of a basin the nominal fit stayed
    // in): the diagnosis is then made again from it, once ([`renominal`])
    let (mut start, mut viscous_start, mut why) = (nom_lin, None, None);
    let pass = loop {
        let first = why.is_none();
        let fitted: Vec<LinExt> = damper_free.iter().chain(&viscous_start).cloned().collect();
        let renominate = first && !opts.budget.expired();
        match diagnose_from(
            &data, &start, &fitted, &idents, opts, &mut stage, &mut steps, renominate,
        ) {
            Ok(mut pass) => {
                pass.notes.splice(0..0, why);
                break pass;
            }
            Err(Renominal { better, note }) => {
                idents.push(better.chain.clone());
                start = renominal::refit_without_damper(&data, &better);
                viscous_start = Some(better);
                why = Some(note);
            }
        }
    };
    let mut d = pass.into_diagnosis(n, data, t0.elapsed().as_secs_f64(), stage.stages);
    d.time_cap = TimeCap::of(&opts.budget, steps.not_tried);
    if d.time_cap.capped {
        d.notes.push(d.time_cap.words());
    }
    Ok(d)
}

/// A better nominal model found by the linear candidates ([`renominal::better_nominal`]),
/// and the note saying so.
struct Renominal {
    better: LinExt,
    note: String,
}

/// One diagnosis from a nominal chain: the parts of [`Diagnosis`] that depend on it.
struct Pass {
    verdict: Effect,
    effects: Vec<Step>,
    nominal: EffectFit,
    ranking: Vec<rank::Ranked>,
    winner: Option<EffectFit>,
    gap: Gap,
    residual: ResidualKind,
    notes: Vec<String>,
    amplitude_mode: Option<amplitude_mode::AmplitudeMode>,
}

impl Pass {
    fn into_diagnosis(
        self,
        masses: usize,
        data: Data,
        seconds: f64,
        stage_cpu_s: Vec<(&'static str, f64)>,
    ) -> Diagnosis {
        Diagnosis {
            verdict: self.verdict,
            effects: self.effects,
            masses,
            nominal: self.nominal,
            ranking: self.ranking,
            winner: self.winner,
            gap: self.gap,
            residual: self.residual,
            data,
            notes: self.notes,
            seconds,
            stage_cpu_s,
            trajectory: None,
            time_cap: TimeCap::default(),
            amplitude_mode: self.amplitude_mode,
        }
    }
}

/// The diagnosis from the nominal chain `nom_lin` (fitted without the motor's damper;
/// `viscous_starts`: fits with it to start the damper's fit from as well): the damper
/// decided, the candidates fitted and ranked, the forward selection, the verdict. With
/// `renominate`, a linear candidate that is the nominal model fitted better stops it
/// before the costly candidates (`Err`: start again from that one).
fn diagnose_from(
    data: &Data,
    nom_lin: &LinExt,
    viscous_starts: &[LinExt],
    idents: &[crate::model::Chain],
    opts: &DiagnoseOptions,
    stage: &mut StageClock,
    steps: &mut Steps,
    renominate: bool,
) -> Result<Pass, Renominal> {
    let n = opts.masses.max(1);
    let viscous = effects::viscous::nominal_with_viscous(data, nom_lin, viscous_starts, idents);
    let nom_lin = viscous.nominal.clone();
    let nominal = effects::finish_linear(data, Effect::None, nom_lin.clone(), vec![], 0);
    stage.lap("nominal");
    let ground_note = nom_lin.ground_spring.then(|| {
        // a ground spring a thousand times the last coupling's stiffness holds the last
        // body still (it moves less than a thousandth of that coupling's deflection)
        let pinned = match nom_lin.chain.stiffness_nm_per_rad.last() {
            Some(&c) if nom_lin.ground_k > 1e3 * c => format!(
                "; it pins the last body ({:.1e} times the last coupling's stiffness): the axis has one body less than --masses {n} says",
                nom_lin.ground_k / c
            ),
            _ => String::new(),
        };
        format!(
            "nominal model with a spring from the last body to the ground (--ground-spring): {:.6e} N m/rad, fitted with the chain; gravity is no candidate{pinned}",
            nom_lin.ground_k
        )
    });

    // what the residual is made of
    let residual = residual_kind(data, &nominal);
    stage.lap("residual");

    let mut candidates = Candidates::new(stage, steps);
    fit_linear_candidates(data, &nominal, idents, &mut candidates);
    if let (false, Some((with, _))) = (viscous.significant, &viscous.with_viscous) {
        // viscous friction not significant on the nominal chain alone (a large gap
        // elsewhere can hide it): each linear effect is also tried on top of it, the
        // damping counted as one more parameter
        fit_linear_candidates_with_viscous(data, with, &mut candidates);
    }
    if renominate && !opts.budget.expired() {
        if let Some((better, from, chi2)) =
            renominal::better_nominal(data, &nominal, &candidates.fits)
        {
            let note = format!(
                "nominal model refitted from the {from} fit, whose own parameter is not significant: chi2 {:.4e} -> {:.4e}; the diagnosis is made from it",
                nominal.chi2, chi2
            );
            return Err(Renominal { better, note });
        }
    }
    let with_viscous = match (viscous.significant, &viscous.with_viscous) {
        (false, Some((with, _))) => Some(with),
        _ => None,
    };
    let ground_as_gravity = fit_extra_mode(
        data,
        &nominal,
        &nom_lin,
        with_viscous,
        n,
        opts.band_hz,
        &mut candidates,
    );
    // the restoring stiffness the data need, if any: the better gravity fit
    let restoring = candidates
        .fits
        .iter()
        .filter(|f| f.effect == Effect::Gravity)
        .chain(&ground_as_gravity)
        .min_by(|a, b| a.chi2.total_cmp(&b.chi2))
        .filter(|g| rank::score(data, nominal.chi2, g) > 0.0)
        .cloned();
    fit_amplitude_candidates(
        data,
        &nom_lin,
        &residual,
        opts.force_nonlinear,
        restoring.as_ref(),
        &mut candidates,
    );
    let (mut fits, mut notes, steps) = (candidates.fits, candidates.notes, candidates.steps);
    notes.insert(0, viscous.note.clone());
    notes.splice(1..1, ground_note);
    if let Some(tp) = &data.torque {
        notes.push(tp.describe());
    }
    let dropped = drop_contradicted_by_reading(data, &mut fits, &mut notes);
    keep_better_gravity(&mut fits, ground_as_gravity);
    gravity_beyond_viscous(data, &mut fits, &viscous, &mut notes);

    let (ranking, first) = rank::rank(data, &nominal, &fits, &residual);
    // several effects at once: forward selection from the best significant candidate,
    // over the candidates that improved on the nominal model significantly on their own
    // (a screen: a candidate that explains nothing alone is not tried on top of another)
    let marginal: Vec<Effect> = ranking
        .iter()
        .filter(|r| r.score > 0.0)
        .map(|r| r.effect)
        .collect();
    // the extra body found on the nominal chain alone: a start of the mode at later steps
    let mode_alone = fits
        .iter()
        .find(|f| f.effect == Effect::UnmodelledMode)
        .map(|f| f.lin.chain.clone());
    let steps = match first {
        Some(i) => {
            let budget = std::cell::RefCell::new(&mut *steps);
            let next = Next {
                screened: &marginal,
                mode_alone: mode_alone.as_ref(),
                level_change: residual.change_local.is_some_and(|w| w.window.significant),
                opts,
                n,
            };
            let (chosen, more) = select::forward(
                data,
                nominal.chi2,
                fits[i].clone(),
                |d, base, named| {
                    let mut steps = budget.borrow_mut();
                    if !steps.go(format!("forward selection step {}", named.len() + 1)) {
                        return Vec::new();
                    }
                    next.fit(d, base, named, &mut steps)
                },
                |base, effect| {
                    // every candidate but `effect` counts as named: only it is fitted
                    let others: Vec<Effect> =
                        Effect::ALL.into_iter().filter(|&e| e != effect).collect();
                    let mut steps = budget.borrow_mut();
                    Next {
                        screened: &[effect],
                        ..next
                    }
                    .fit(data, base, &others, &mut steps)
                    .into_iter()
                    .find(|f| f.effect == effect)
                },
            );
            notes.extend(more);
            chosen
        }
        None => Vec::new(),
    };
    stage.lap("select");
    // named only when the set explains the gap; otherwise the gap is noise (`none`) or
    // real but unexplained
    let explained = steps
        .last()
        .map(|s| rank::explained_fraction(data, nominal.chi2, s.fit.chi2));
    let effects = match explained {
        Some(x) if x > rank::EXPLAINS => steps,
        Some(x) => {
            let names: Vec<&str> = steps.iter().map(|s| s.effect.name()).collect();
            notes.push(format!(
                "{} significant but explains only {:.0} % of the gap beyond the noise (needs more than {:.0} %): not named",
                names.join(" + "),
                100.0 * x,
                100.0 * rank::EXPLAINS
            ));
            Vec::new()
        }
        None => Vec::new(),
    };
    // a set whose model ends farther from the measurement than the nominal model, in the
    // gap the report shows (all lines, inverse-variance weighted), explains nothing there,
    // whatever its chi² on the lines it was fitted to: not named
    let mut effects = effects;
    if let Some(last) = effects.last() {
        let with = gap_of(data, &nominal, Some(&last.fit));
        if with.after_rms_db > with.before_rms_db {
            let names: Vec<&str> = effects.iter().map(|s| s.effect.name()).collect();
            notes.push(format!(
                "{} lowers the chi2 but widens the gap ({:.3} -> {:.3} dB over all lines): not named",
                names.join(" + "),
                with.before_rms_db,
                with.after_rms_db
            ));
            effects.clear();
        }
    }
    // a lag the torque reading places after the torque explains the gap better: out of
    // the library
    if let Some(note) = after_torque::better_than_named(data, &effects, &dropped) {
        notes.push(note);
        effects.clear();
    }
    // a set of linear effects cannot explain an FRF that changes between levels
    if level_change::linear_set_misses(data, &nominal, &effects, &residual, &mut notes) {
        effects.clear();
    }
    let mut verdict = match effects.first() {
        Some(s) => s.effect,
        None if residual.gap_is_real() => Effect::Unexplained,
        None => Effect::None,
    };
    // unexplained, and the FRF changes between levels: does a mode of that band move?
    let amplitude_mode = (verdict == Effect::Unexplained && residual.changed)
        .then(|| amplitude_mode_of(data, &residual, &mut notes))
        .flatten();
    if amplitude_mode.as_ref().is_some_and(|a| a.named.is_some()) {
        verdict = Effect::AmplitudeDependentMode;
    }
    let winner = effects.first().map(|s| s.fit.clone());
    let gap = gap_of(data, &nominal, effects.last().map(|s| &s.fit));
    stage.lap("rank");
    Ok(Pass {
        verdict,
        effects,
        nominal,
        ranking,
        winner,
        gap,
        residual,
        notes,
        amplitude_mode,
    })
}

/// The local modal analysis of the band where the FRF changes most between levels
/// ([`amplitude_mode`]), its result in `notes`.
fn amplitude_mode_of(
    data: &Data,
    residual: &ResidualKind,
    notes: &mut Vec<String>,
) -> Option<amplitude_mode::AmplitudeMode> {
    let Some(w) = residual.change_local.filter(|w| w.window.significant) else {
        notes.push(
            "amplitude-dependent mode: not analysed (the FRF's change between levels is not localised to a significant run of lines)".into(),
        );
        return None;
    };
    let change = [w.window.lo_hz, w.window.hi_hz];
    match amplitude_mode::of_data(data, change) {
        Some(a) => {
            notes.push(format!("amplitude-dependent mode: {}", a.words()));
            Some(a)
        }
        None => {
            notes.push(format!(
                "amplitude-dependent mode: the modes of {:.2}-{:.2} Hz could not be fitted at the lowest level, or at no other (not identifiable)",
                change[0], change[1]
            ));
            None
        }
    }
}

/// What the later steps of the forward selection fit their candidates with.
#[derive(Clone, Copy)]
struct Next<'a> {
    /// The amplitude-dependent candidates tried (those significant alone; all with
    /// `--all-effects`).
    screened: &'a [Effect],
    /// The chain with the extra body found on the nominal chain alone: its body is one
    /// more start of the mode's fit on top of other effects (besides the starts from the
    /// bands of the gap that remains).
    mode_alone: Option<&'a crate::model::Chain>,
    /// The FRF changes between levels beyond the noise in a local band: on top of linear
    /// effects only, which cannot explain that, the amplitude-dependent candidates are
    /// tried even where they did not improve on the nominal model alone (a current loop
    /// that dominates the gap hides a hardening's part of it from a fit without the loop:
    /// dev C 70201).
    level_change: bool,
    opts: &'a DiagnoseOptions,
    n: usize,
}

impl Next<'_> {
    /// The candidates for the next step of the forward selection on `data` (the measurement,
    /// with amplitude-dependent effects found before divided out), on top of `base` (the chain
    /// and linear extensions found so far): the linear ones and those in `screened` (all with
    /// `--all-effects`), but not `named`.
    fn fit(
        &self,
        data: &Data,
        base: &LinExt,
        named: &[Effect],
        steps: &mut Steps,
    ) -> Vec<EffectFit> {
        let Next {
            screened, opts, n, ..
        } = *self;
        let step = named.len() + 1;
        // the linear candidates are always tried (cheap; a large gap of another effect can
        // keep one from improving on the nominal model alone: C 70300's delay beside
        // gravity); the amplitude-dependent ones only when they did on their own, or when
        // only linear effects are named and the FRF changes between levels
        let changes_unexplained = self.level_change && named.iter().all(|e| e.is_linear());
        // an amplitude-dependent effect shows itself by the change of the FRF between
        // levels: where the one named before is divided out (`data`) and leaves no
        // significant change, a further one has nothing of its own to show beside what a
        // linear effect would (and its fits, simulations, would cost for nothing)
        let change_left = named.iter().all(|e| e.is_linear())
            || data.levels.len() < 2
            || level_change::between_levels(data).changed;
        let mut wanted = |e: Effect| {
            !named.contains(&e)
                && (opts.force_nonlinear
                    || e.is_linear()
                    || (change_left && (screened.contains(&e) || changes_unexplained)))
                && steps.go(format_args!("{e} (forward selection step {step})"))
        };
        let mut fits: Vec<EffectFit> = Vec::new();
        if wanted(Effect::TimeDelay) {
            fits.extend(effects::delay::fit(data, base));
        }
        if wanted(Effect::CurrentLoop) {
            fits.extend(effects::current_loop::fit(data, base));
        }
        if wanted(Effect::Gravity) && !base.ground_spring {
            fits.extend(effects::gravity::fit(data, base, &[], &[]));
        }
        if wanted(Effect::UnmodelledMode) {
            let here = effects::finish_linear(data, Effect::None, base.clone(), vec![], 0);
            let freqs = mode_start_freqs(data, &here);
            let alone: Vec<crate::model::Chain> = self
                .mode_alone
                .filter(|c| c.masses() == base.chain.masses() + 1)
                .map(|c| {
                    let mut ch = base.chain.clone();
                    ch.inertia_kgm2.extend(c.inertia_kgm2.last());
                    ch.stiffness_nm_per_rad
                        .extend(c.stiffness_nm_per_rad.last());
                    ch.damping_nms_per_rad.extend(c.damping_nms_per_rad.last());
                    ch
                })
                .into_iter()
                .collect();
            let starts = effects::mode::starts(&base.chain, &freqs, &alone);
            // an extra body that is the ground is gravity with a load-ground damper (as in
            // the first step, [`fit_extra_mode`])
            fits.extend(
                effects::mode::fit(data, base, &starts, &opts.budget).map(|f| {
                    match (!base.ground_spring)
                        .then(|| effects::gravity::from_ground_mode(&f))
                        .flatten()
                    {
                        Some(g) => g,
                        None => f,
                    }
                }),
            );
        }
        if wanted(Effect::CoulombFriction) {
            fits.extend(effects::friction::fit(data, base));
        }
        if base.chain.masses() == n {
            // the spring effects act on the nominal couplings
            if wanted(Effect::Backlash) {
                fits.extend(effects::backlash::fit(data, base));
            }
            if wanted(Effect::HardeningStiffness) {
                fits.extend(effects::hardening::fit(data, base));
            }
        }
        let _ = drop_contradicted_by_reading(data, &mut fits, &mut Vec::new());
        fits
    }
}

/// Drop the candidates the drive's torque reading contradicts, if there is one
/// ([`torque_path::drop_contradicted`], against what noise alone gives a fit on `data`);
/// returns the dropped fits.
fn drop_contradicted_by_reading(
    data: &Data,
    fits: &mut Vec<EffectFit>,
    notes: &mut Vec<String>,
) -> Vec<EffectFit> {
    match &data.torque {
        Some(tp) => {
            let expected = data.noise.mean * data.lines() as f64;
            torque_path::drop_contradicted(tp, data.levels[0].io_delay, expected, fits, notes)
        }
        None => Vec::new(),
    }
}

/// Start frequencies of an extra mode from the gap of `model`: the four most significant
/// localised bands, each at its peak and the two ends of its core (where the error is at
/// least half its largest: a band can span the whole spectrum when the data are clean, its
/// core is where the missing pair is).
fn mode_start_freqs(data: &Data, model: &EffectFit) -> Vec<f64> {
    let mut bands: Vec<Band> = Vec::new();
    for (i, l) in data.levels.iter().enumerate() {
        bands.extend(localise::bands(
            i,
            &l.f,
            &l.h,
            &l.var,
            &model.model[i],
            l.averages,
        ));
    }
    bands.sort_by(|a, b| (b.mean_z2 * b.lines as f64).total_cmp(&(a.mean_z2 * a.lines as f64)));
    bands
        .iter()
        .take(4)
        .flat_map(|b| [b.peak_hz, b.core_lo_hz, b.core_hi_hz])
        .collect()
}

/// The level with the highest torque RMS.
pub(crate) fn top_level(data: &Data) -> usize {
    (0..data.levels.len())
        .max_by(|&a, &b| {
            data.levels[a]
                .torque_rms
                .total_cmp(&data.levels[b].torque_rms)
        })
        .unwrap()
}

/// The nominal chain of `n` bodies, fitted jointly to every level. Every level's
/// identification is a start, highest level first (a strongly nonlinear level can make its
/// own one fail, e.g. a spring hardened far beyond its small-signal value); the joint fit
/// with the lowest chi² over all levels is the nominal model. When no level gives `n`
/// bodies: one body less, plus one appended near the top of the band.
fn fit_nominal(
    data: &Data,
    n: usize,
    band: Option<[f64; 2]>,
    budget: &FitBudget,
    starts: &mut Vec<crate::model::Chain>,
) -> Result<LinExt, DiagnoseError> {
    let mut order: Vec<usize> = (0..data.levels.len()).collect();
    order.sort_by(|&a, &b| {
        data.levels[b]
            .torque_rms
            .total_cmp(&data.levels[a].torque_rms)
    });
    let fit_joint = |start: crate::model::Chain| {
        effects::fit_linear(
            data,
            &data.targets,
            Lin::None,
            &LinExt::nominal(start.clone()),
            60,
        )
        .map(|r| r.0)
        .unwrap_or_else(|| LinExt::nominal(start))
    };
    let mut best: Option<(LinExt, f64)> = None;
    for &i in &order {
        if best.is_some() && budget.expired() {
            // the time cap: the best joint fit so far is the nominal model
            budget.skip_order();
            break;
        }
        let Some(start) = nominal_start(&data.levels[i], n, band, budget) else {
            continue;
        };
        starts.push(start.clone());
        let lin = fit_joint(start);
        let chi2 = data.chi2_of(&lin);
        if !chi2.is_finite() {
            // a degenerate chain (its response not finite on some line) is no nominal model
            continue;
        }
        let done = data.within_noise(chi2);
        if best.as_ref().is_none_or(|b| chi2 < b.1) {
            best = Some((lin, chi2));
        }
        if done {
            break;
        }
    }
    if let Some((lin, _)) = best {
        return Ok(lin);
    }
    let top = top_level(data);
    let start = n
        .checked_sub(1)
        .filter(|&m| m > 0)
        .and_then(|m| nominal_start(&data.levels[top], m, band, budget))
        .and_then(|c| {
            effects::mode::starts(&c, &[0.5 * data.f_max()], &[])
                .into_iter()
                .nth(1)
        })
        .ok_or(DiagnoseError::NoNominal(top, n))?;
    Ok(fit_joint(start))
}

/// The nominal chain of `n` bodies with a spring to the ground ([`ground_spring`]), fitted
/// jointly to every level from the free chains identified on each level (kept in
/// `starts`, the other fits' starts) with a grid of ground stiffnesses, and for one body
/// from its impedance's least squares: the start with the lowest chi² after the joint fit
/// with the motor's damper (a grounded body without damping has an infinite resonance, no
/// fit starts from it). Returns that fit with its damper taken out and the chain and
/// ground spring refitted (the nominal model before the damper's decision,
/// [`effects::viscous`]), and the fit with the damper (a start of that decision).
fn fit_grounded_nominal(
    data: &Data,
    n: usize,
    band: Option<[f64; 2]>,
    budget: &FitBudget,
    starts: &mut Vec<crate::model::Chain>,
) -> Result<(LinExt, Option<LinExt>), DiagnoseError> {
    for l in &data.levels {
        if let Some(c) = nominal_start(l, n, band, budget) {
            starts.push(c);
        }
    }
    let mut grounded = ground_spring::starts(data, starts);
    grounded.retain(|s| s.chain.masses() == n);
    let jt_w = |s: &LinExt| s.chain.total_inertia() * 2.0 * std::f64::consts::PI * data.f_min();
    let mut best: Option<(LinExt, f64)> = None;
    for mut s in grounded {
        if s.motor_b <= 0.0 {
            // a tenth of critical damping of the ground resonance, at least a little
            s.motor_b = (0.2 * (s.ground_k * s.chain.total_inertia()).sqrt()).max(1e-3 * jt_w(&s));
        }
        let lin = effects::fit_linear(data, &data.targets, Lin::Viscous, &s, 60)
            .map(|r| r.0)
            .unwrap_or(s);
        let chi2 = data.chi2_of(&lin);
        if chi2.is_finite() && best.as_ref().is_none_or(|b| chi2 < b.1) {
            best = Some((lin, chi2));
        }
    }
    let damped = best
        .map(|b| b.0)
        .ok_or(DiagnoseError::NoNominal(top_level(data), n))?;
    let undamped = renominal::refit_without_damper(data, &damped);
    Ok((undamped, Some(damped)))
}

/// The candidates fitted so far, with a note (wall time, or "no fit") per candidate and
/// the CPU time of each as a stage.
struct Candidates<'a> {
    fits: Vec<EffectFit>,
    notes: Vec<String>,
    clock: std::time::Instant,
    stage: &'a mut StageClock,
    /// The time cap: a candidate is fitted only while it has not passed.
    steps: &'a mut Steps,
}

impl<'a> Candidates<'a> {
    fn new(stage: &'a mut StageClock, steps: &'a mut Steps) -> Self {
        Candidates {
            fits: Vec::new(),
            notes: Vec::new(),
            clock: std::time::Instant::now(),
            stage,
            steps,
        }
    }

    /// Fit `effect` with `fit` and record it, unless the time cap has passed (then it is
    /// listed as not tried).
    fn fit(&mut self, effect: Effect, fit: impl FnOnce() -> Option<EffectFit>) {
        if self.steps.go(effect) {
            self.push(fit(), effect);
        }
    }

    /// Record the fit of `effect` (`None`: it could not be fitted).
    fn push(&mut self, fit: Option<EffectFit>, effect: Effect) {
        self.lap(effect);
        match fit {
            Some(f) => self.fits.push(f),
            None => self.notes.push(format!("{effect}: no fit")),
        }
    }

    /// Record that `effect` was fitted but is not a candidate, and why.
    fn skip(&mut self, effect: Effect, why: String) {
        self.lap(effect);
        self.notes.push(why);
    }

    /// Close the stage of `effect`: its wall time as a note, its CPU time as a stage.
    fn lap(&mut self, effect: Effect) {
        self.notes.push(format!(
            "{effect}: {:.2} s",
            self.clock.elapsed().as_secs_f64()
        ));
        self.stage.lap(effect.name());
        self.clock = std::time::Instant::now();
    }

    /// Whether a candidate already leaves only noise.
    fn explained(&self, data: &Data) -> bool {
        self.fits.iter().any(|f| data.within_noise(f.chi2))
    }
}

/// The linear candidates that extend the nominal chain's transfer function: time delay,
/// current loop, gravity.
fn fit_linear_candidates(
    data: &Data,
    nominal: &EffectFit,
    idents: &[crate::model::Chain],
    c: &mut Candidates,
) {
    let nom_lin = &nominal.lin;
    let budget = c.steps.budget.clone();
    c.fit(Effect::TimeDelay, || {
        let more = effects::delay::reidentified(data, nom_lin, &budget);
        effects::delay::fit_from(data, nom_lin, &more)
    });
    c.fit(Effect::CurrentLoop, || {
        effects::current_loop::fit(data, nom_lin)
    });
    if nom_lin.ground_spring {
        c.notes.push(
            "gravity: not a candidate (the nominal model has the spring to the ground)".into(),
        );
        return;
    }
    c.fit(Effect::Gravity, || {
        effects::gravity::fit(data, nom_lin, idents, &mode_start_freqs(data, nominal))
    });
}

/// The linear candidates on the nominal chain with viscous friction to the ground that was
/// not significant alone: kept only where better than the same effect without it by more
/// than the damping's BIC price (one parameter more, counted in `added`).
fn fit_linear_candidates_with_viscous(data: &Data, with: &LinExt, c: &mut Candidates) {
    let pen = (data.lines() as f64).ln();
    let fits: [(Effect, fn(&Data, &LinExt) -> Option<EffectFit>); 2] = [
        (Effect::TimeDelay, effects::delay::fit),
        (Effect::CurrentLoop, effects::current_loop::fit),
    ];
    for (effect, fit) in fits {
        if !c.steps.go(format_args!("{effect} (with viscous friction)")) {
            continue;
        }
        let Some(mut f) = fit(data, with) else {
            continue;
        };
        f.added += 1;
        f.params.push(effects::EffectFit::param(
            "viscous_nms_per_rad",
            f.lin.motor_b,
            f64::NAN,
        ));
        match c.fits.iter().position(|g| g.effect == effect) {
            Some(i) if c.fits[i].chi2 - f.chi2 > pen => c.fits[i] = f,
            Some(_) => {}
            None => c.fits.push(f),
        }
    }
}

/// Gravity is a ground stiffness plus a ground damper: its stiffness must be significant
/// beyond viscous friction alone (the damper without the spring), else the candidate is
/// viscous friction in disguise (`m g l` at its floor with a meaningless tiny
/// uncertainty) and is dropped with a note.
fn gravity_beyond_viscous(
    data: &Data,
    fits: &mut Vec<EffectFit>,
    viscous: &effects::viscous::ViscousNominal,
    notes: &mut Vec<String>,
) {
    let Some((_, c_visc)) = viscous.with_viscous else {
        return;
    };
    let pen = (data.lines() as f64).ln();
    if let Some(i) = fits.iter().position(|f| f.effect == Effect::Gravity) {
        let reduction = c_visc - fits[i].chi2;
        // the reduction against the line noise, scaled by the model's own excess
        let scale = (fits[i].chi2 / data.lines().max(1) as f64).max(1.0);
        let z2 = reduction / scale;
        let threshold = effects::viscous::SIGNIFICANT_SIGMA.powi(2);
        if reduction <= pen || z2 < threshold {
            notes.push(format!(
                "gravity dropped: its ground stiffness lowers chi2 by only {reduction:.4e} below viscous friction alone ({z2:.1} scaled; needs {threshold:.0} and the BIC price {pen:.1})"
            ));
            fits.remove(i);
        }
    }
}

/// The extra body (an unmodelled mode), started from the identification with one body more
/// and from the most significant localised bands of the nominal model's gap; also on the
/// nominal chain with the viscous friction that was not significant alone (`with_viscous`),
/// kept where that pays the damping's BIC price. Returns the gravity refit when the best
/// "extra body" is far heavier than the rest of the axis: that is the ground, its spring a
/// restoring stiffness on the last body.
fn fit_extra_mode(
    data: &Data,
    nominal: &EffectFit,
    nom_lin: &LinExt,
    with_viscous: Option<&LinExt>,
    n: usize,
    band: Option<[f64; 2]>,
    c: &mut Candidates,
) -> Option<EffectFit> {
    if !c.steps.go(Effect::UnmodelledMode) {
        return None;
    }
    let budget = &c.steps.budget.clone();
    let mut extra: Vec<crate::model::Chain> = Vec::new();
    if let Some(ch) = nominal_start(&data.levels[top_level(data)], n + 1, band, budget) {
        extra.push(ch);
    }
    // candidate frequencies of the extra mode: the most significant localised bands
    let freqs = mode_start_freqs(data, nominal);
    let mode_starts = effects::mode::starts(&nom_lin.chain, &freqs, &extra);
    let mut mode_fit = effects::mode::fit(data, nom_lin, &mode_starts, budget);
    let with_viscous =
        with_viscous.filter(|_| c.steps.go("unmodelled_mode (with viscous friction)"));
    if let Some(with) = with_viscous {
        let here = effects::finish_linear(data, Effect::None, with.clone(), vec![], 0);
        let freqs = mode_start_freqs(data, &here);
        let starts = effects::mode::starts(&with.chain, &freqs, &extra);
        if let Some(mut f) = effects::mode::fit_as(data, with, &starts, Lin::ModeViscous, budget) {
            let pen = (data.lines() as f64).ln();
            if mode_fit.as_ref().is_none_or(|m| m.chi2 - f.chi2 > pen) {
                f.added += 1;
                f.params.push(effects::EffectFit::param(
                    "viscous_nms_per_rad",
                    f.lin.motor_b,
                    f64::NAN,
                ));
                mode_fit = Some(f);
            }
        }
    }
    let Some(mf) = mode_fit else {
        c.push(None, Effect::UnmodelledMode);
        return None;
    };
    // with a spring to the ground in the nominal model, a heavy extra body is no gravity
    let as_ground = if nom_lin.ground_spring {
        None
    } else {
        effects::gravity::from_ground_mode(&mf)
    };
    match as_ground {
        // the extra body is the ground: the fit is gravity's (refitted as such too; the
        // better of the two), and no unmodelled mode
        Some(same) => {
            let ground = &mf.lin.chain.inertia_kgm2;
            c.skip(Effect::UnmodelledMode, format!(
                "unmodelled_mode: its extra body ({:.3e} kg m2) is the ground (20 times the rest of the chain): the fit is a restoring stiffness, taken as gravity",
                ground[ground.len() - 1]
            ));
            let refit = effects::gravity::from_ground_body(data, &mf.lin.chain);
            Some(match refit {
                Some(r) if r.chi2 < same.chi2 => r,
                _ => same,
            })
        }
        None => {
            c.push(Some(mf), Effect::UnmodelledMode);
            None
        }
    }
}

/// The amplitude-dependent candidates (simulated in the time domain): Coulomb friction,
/// backlash, hardening stiffness. Skipped when a linear candidate already leaves only
/// noise (a simulated one cannot beat it significantly) or when nothing changes between
/// levels and no distortion shows at the detection lines, unless `force`.
fn fit_amplitude_candidates(
    data: &Data,
    nom_lin: &LinExt,
    residual: &ResidualKind,
    force: bool,
    restoring: Option<&EffectFit>,
    c: &mut Candidates,
) {
    // a linear candidate within the noise over all lines does not explain an FRF that
    // changes significantly between levels (no linear model does)
    if c.explained(data) && !force && !residual.nonlinear {
        c.notes.push(
            "amplitude-dependent candidates not simulated: a linear candidate leaves only noise"
                .into(),
        );
        return;
    }
    if !(residual.nonlinear || force) {
        c.notes.push(
            "amplitude-dependent candidates not simulated: no significant change between levels and no distortion at the detection lines".into(),
        );
        return;
    }
    c.fit(Effect::CoulombFriction, || {
        effects::friction::fit(data, nom_lin)
    });
    c.fit(Effect::Backlash, || effects::backlash::fit(data, nom_lin));
    if !c.steps.go(Effect::HardeningStiffness) {
        return;
    }
    // hardening stiffens the springs at the highest level: start from the chain the
    // lowest level sees
    let low = (0..data.levels.len())
        .min_by(|&a, &b| {
            data.levels[a]
                .torque_rms
                .total_cmp(&data.levels[b].torque_rms)
        })
        .unwrap();
    let low_lin = effects::fit_linear(data, &data.targets[low..low + 1], Lin::None, nom_lin, 40)
        .map(|r| r.0)
        .unwrap_or_else(|| nom_lin.clone());
    // a cubic spring to the ground also from the chain that holds the load by a linear
    // one (gravity's fit, significant on its own): a free nominal chain can have taken the
    // load for the ground, and a cubic spring on an immovable body changes nothing (dev
    // B 60304: named `gravity` before; dev A 50402, whose load at 3.9e8 kg m2 even the
    // extra-body fit keeps as the ground, is still missed)
    let fits = [
        effects::hardening::fit(data, &low_lin),
        restoring.and_then(|g| effects::hardening::fit_ground_from_restoring(data, g)),
        effects::hardening::fit_ground_from_spectra(data, nom_lin),
    ];
    c.push(
        fits.into_iter()
            .flatten()
            .min_by(|a, b| a.chi2.total_cmp(&b.chi2)),
        Effect::HardeningStiffness,
    );
}

/// The better of the two gravity fits (the candidate's own, and the extra body refitted
/// as the ground).
fn keep_better_gravity(fits: &mut Vec<EffectFit>, ground_as_gravity: Option<EffectFit>) {
    let Some(g) = ground_as_gravity else { return };
    match fits.iter().position(|f| f.effect == Effect::Gravity) {
        Some(i) if fits[i].chi2 <= g.chi2 => {}
        Some(i) => fits[i] = g,
        None => fits.push(g),
    }
}

fn residual_kind(data: &Data, nominal: &EffectFit) -> ResidualKind {
    let lines = data.lines() as f64;
    let reduced = nominal.chi2 / lines;
    let levels: Vec<LevelDistortion> = data
        .levels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let mut d = distortion::level_distortion(i, l.torque_rms, l.nonexcited.as_ref());
            d.realisation_excess_db = l
                .spread_var
                .as_ref()
                .and_then(|s| distortion::realisation_excess_db(s, &l.var));
            d
        })
        .collect();
    let level_change::Changes {
        changes,
        change_local,
        changed,
    } = level_change::between_levels(data);
    // the same 6 dB for the realisations' spread over the noise as for the detection lines
    let nonlinear = changed
        || levels.iter().any(|l| {
            l.detection_excess_db.is_some_and(|d| d > 6.0)
                || l.realisation_excess_db.is_some_and(|d| d > 6.0)
        });
    // the nominal model's gap, line by line: its most significant run of lines
    let z2: Vec<Vec<f64>> = data
        .levels
        .iter()
        .zip(&nominal.model)
        .map(|(l, m)| localise::z2(&l.h, &l.var, m))
        .collect();
    let dofs: Vec<Vec<f64>> = data
        .levels
        .iter()
        .map(|l| vec![noise::dof(l.averages); l.f.len()])
        .collect();
    let local = scan::scan(
        &data
            .levels
            .iter()
            .enumerate()
            .map(|(i, l)| scan::Series {
                f: &l.f,
                z2: &z2[i],
                dof: &dofs[i],
            })
            .collect::<Vec<_>>(),
    )
    .map(Located::from);
    // the gap is judged over the whole band: the localised scan is reported, not yet a
    // judge (on the world benchmark it called a gap of one to three lines real where the
    // nominal fit or the sweep's estimate is off there by a few standard deviations: cases
    // without effect 36 -> 33 of 50 right); it decides only whether the FRF changes
    // between levels, i.e. whether the amplitude-dependent candidates are simulated
    let within_noise = data.within_noise(nominal.chi2);
    // linear model error: the residual normalised by the model is the same at every level
    ResidualKind {
        reduced_chi2: reduced,
        within_noise,
        changed,
        nonlinear,
        linear_model_error: !within_noise && !changed,
        local,
        change_local,
        levels,
        changes,
    }
}

/// Systematic RMS of the log-complex gap, magnitude and phase parts: inverse-variance
/// weighted over all lines with the expected noise contribution removed,
/// `sqrt(max(0, sum w (|e|² - s²)) / sum w)`, `s² = var/|H|²`, `w = 1/s²` (the weighted
/// mean of `|e|²` is `chi²/sum w`; noise adds `lines/sum w`). Also the plain unweighted RMS.
pub fn rms_parts(data: &Data, model: &[Vec<Complex64>]) -> (f64, f64, f64, f64) {
    let (mut s, mut sm, mut sp, mut sw, mut k, mut raw) = (0.0, 0.0, 0.0, 0.0, 0usize, 0.0);
    for (l, m) in data.levels.iter().zip(model) {
        for ((h, m), v) in l.h.iter().zip(m).zip(&l.var) {
            let e = (h / m).ln();
            let s2 = v / h.norm_sqr();
            let w = 1.0 / s2;
            s += w * (e.norm_sqr() - s2);
            sm += w * (e.re * e.re - 0.5 * s2);
            sp += w * (e.im * e.im - 0.5 * s2);
            sw += w;
            raw += e.norm_sqr();
            k += 1;
        }
    }
    let sw = sw.max(1e-300);
    (
        localise::DB_PER_NEPER * (s.max(0.0) / sw).sqrt(),
        localise::DB_PER_NEPER * (sm.max(0.0) / sw).sqrt(),
        (sp.max(0.0) / sw).sqrt().to_degrees(),
        localise::DB_PER_NEPER * (raw / k.max(1) as f64).sqrt(),
    )
}

fn gap_of(data: &Data, nominal: &EffectFit, winner: Option<&EffectFit>) -> Gap {
    let after_model = winner.map(|w| &w.model).unwrap_or(&nominal.model);
    let (b, bm, bp, braw) = rms_parts(data, &nominal.model);
    let (a, am, ap, araw) = rms_parts(data, after_model);
    let mut noise = 0.0;
    for l in &data.levels {
        for (h, v) in l.h.iter().zip(&l.var) {
            noise += v / h.norm_sqr();
        }
    }
    let noise = localise::DB_PER_NEPER * (noise / data.lines().max(1) as f64).sqrt();
    let mut bands = Vec::new();
    for (i, l) in data.levels.iter().enumerate() {
        for band in localise::bands(i, &l.f, &l.h, &l.var, &nominal.model[i], l.averages) {
            let idx: Vec<usize> = (0..l.f.len())
                .filter(|&k| l.f[k] >= band.lo_hz && l.f[k] <= band.hi_hz)
                .collect();
            let h: Vec<Complex64> = idx.iter().map(|&k| l.h[k]).collect();
            let m: Vec<Complex64> = idx.iter().map(|&k| after_model[i][k]).collect();
            let after = localise::gap_rms_db(&h, &m);
            bands.push((band, after));
        }
    }
    Gap {
        before_rms_db: b,
        after_rms_db: a,
        before_raw_rms_db: braw,
        after_raw_rms_db: araw,
        before_mag_db: bm,
        after_mag_db: am,
        before_phase_deg: bp,
        after_phase_deg: ap,
        noise_rms_db: noise,
        bands,
    }
}

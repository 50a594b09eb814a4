use super::estimate::{estimate_frf, mobility_equivalent, EstimatedFrf};
use super::summary::ModelSummary;
use crate::frf::{supported_band, Frf, FrfError, FrfKind};
use crate::identify::detect::{
    detect_pairs, ArRPair, DetectOptions, Detection, ExtremumKind, RejectedCandidate,
};
use crate::identify::error::IdentifyError;
use crate::identify::exact::{chain_from_spectra, with_coupling_damping};
use crate::identify::fit::{
    coarse_fit, fit_chain, select_confirmed_order, ChainFit, FitOptions, OrderCandidate,
};
use crate::identify::ground_damper::{self, GroundDamping};
use crate::identify::inertia::{estimate_inertia, estimate_inertia_below_pairs, InertiaEstimate};
use crate::identify::paper::{step_by_step, StepByStep};
use crate::model::{Chain, ModelError, SampledChain};
use crate::recording::Recording;
use serde::Serialize;

/// Errors of the analysis of a recording.
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    #[error(
        "the recording has no motion column (position_rad, velocity_rad_s or acceleration_rad_s2)"
    )]
    NoMotion,
    #[error("the recording has {samples} samples; at least {needed} are needed")]
    TooShort { samples: usize, needed: usize },
    #[error("no frequency line with a usable estimate is left in the band")]
    NoLines,
    #[error("{masses} bodies asked for: a chain has 1 to {max} bodies here")]
    Masses { masses: usize, max: usize },
    #[error("FRF estimation: {0}")]
    Frf(#[from] FrfError),
    #[error("identification: {0}")]
    Identify(#[from] IdentifyError),
    #[error("model: {0}")]
    Model(#[from] ModelError),
}

/// Options of [`analyze`].
#[derive(Debug, Clone)]
pub struct AnalysisOptions {
    /// Number of bodies of the model; chosen automatically when `None`.
    pub masses: Option<usize>,
    /// Largest number of bodies the automatic order choice considers.
    pub max_masses: usize,
    /// Analysis band [Hz]; the excited band when `None`.
    pub band_hz: Option<[f64; 2]>,
    /// Refinement options (starts, seed, ...). `delay_samples` is taken from the recording.
    pub fit: FitOptions,
    /// Detection thresholds.
    pub detect: DetectOptions,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        AnalysisOptions {
            masses: None,
            max_masses: 6,
            band_hz: None,
            fit: FitOptions {
                starts: 20,
                ..FitOptions::default()
            },
            detect: DetectOptions::default(),
        }
    }
}

/// Where the total inertia came from.
#[derive(Debug, Clone, Serialize)]
pub struct TotalInertia {
    /// Total inertia [kg m^2] (units of torque / (rad/s^2) when the torque column holds a
    /// current or force instead).
    pub j_kgm2: f64,
    /// One-sigma uncertainty [kg m^2] (0 when given by the user).
    pub std_kgm2: f64,
    /// "sidecar" (given) or "low_frequency_gain" (paper step 1 on the measured FRF).
    pub source: &'static str,
    /// The estimate from the gain, when computed.
    pub estimate: Option<InertiaEstimate>,
}

/// Everything one analysis found, step by step.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The measured FRF (and how it was estimated).
    pub measured: EstimatedFrf,
    /// Sample rate [Hz].
    pub sample_rate_hz: f64,
    /// Whole samples of command delay assumed (from the recording's sidecar).
    pub delay_samples: u32,
    /// Total inertia (paper step 1).
    pub total_inertia: Option<TotalInertia>,
    /// Detected anti-resonance / resonance pairs.
    pub detection: Detection,
    /// The paper's step-by-step algorithm on the detected pairs.
    pub paper: Option<StepByStep>,
    /// The exact inverse of the detected spectra (undamped chain).
    pub exact: Option<Chain>,
    /// The refined model (when the FRF kind supports the chain fit).
    pub fit: Option<ChainFit>,
    /// Candidate orders considered by the automatic choice, with their criteria.
    pub orders: Vec<OrderCandidate>,
    /// The identified model, summarised for reports and JSON.
    pub model: Option<ModelSummary>,
    /// The identified model's FRF on the measured lines, on the same (sampled) footing.
    pub model_frf: Option<Frf>,
    /// Remarks for the reader: approximations, assumptions, limits.
    pub notes: Vec<String>,
    /// The time cap (`opts.fit.budget`) and whether it stopped the fit early; `None`
    /// without a cap.
    pub time_cap: Option<super::TimeCap>,
    /// The band the detection and the fit used when no band was given and the estimate's
    /// uncertainty left lines out ([`crate::frf::supported_band`]: lines whose windowed
    /// SNR `|H| / sigma_H` is below 1 carry no information); `None` when every line was
    /// used or a band was given.
    pub supported_band_hz: Option<[f64; 2]>,
    /// The damper from the motor to the ground seen on the lowest lines, when significant,
    /// and the measured FRF with it taken out ([`crate::identify::ground_damper`]): the
    /// pairs, the total inertia and the free chain are identified on that FRF; the model's
    /// FRF (`model_frf`) has the damper put back, on the footing of `measured`.
    pub ground_damper: Option<GroundDamperOut>,
}

/// A ground damper taken out of the measurement before the chain was identified.
#[derive(Debug, Clone)]
pub struct GroundDamperOut {
    /// The damper [N m s/rad] and its standard deviation.
    pub damping: GroundDamping,
    /// The measured FRF without it: what the free chain was fitted to.
    pub free_frf: Frf,
}

impl Analysis {
    /// The FRF the chain is identified on: the measured one, or the measured one with the
    /// ground damper taken out.
    pub fn fitted_frf(&self) -> &Frf {
        self.ground_damper
            .as_ref()
            .map_or(&self.measured.frf, |g| &g.free_frf)
    }
}

/// Analyse a recording: estimate its FRF and identify the compliant chain behind it.
///
/// With a capped `opts.fit.budget`, starts and orders not begun when the cap passes are
/// skipped and the best model so far is returned; `Analysis::time_cap` and a note say so.
pub fn analyze(rec: &Recording, opts: &AnalysisOptions) -> Result<Analysis, AnalysisError> {
    let measured = estimate_frf(rec, opts.band_hz)?;
    analyze_estimate(rec, measured, opts)
}

/// The measurement alone: the FRF estimated as [`analyze`] estimates it, with no pairs
/// detected and no model identified (a Bode plot of what was measured, which a record
/// whose lines are too few or too noisy for an identification still has).
pub fn measure_only(rec: &Recording, opts: &AnalysisOptions) -> Result<Analysis, AnalysisError> {
    let measured = estimate_frf(rec, opts.band_hz)?;
    let mut notes = measurement_notes(rec, &measured);
    let supported = supported_lines(&measured.frf, opts, &mut notes);
    let nothing = Detection {
        pairs: Vec::new(),
        peaks: Vec::new(),
        unconfirmed: Vec::new(),
        rejected: Vec::new(),
        notes: Vec::new(),
    };
    let delay = rec.sidecar.io_delay_samples.unwrap_or(0);
    Ok(before_the_model(
        rec, measured, delay, nothing, notes, supported, None,
    ))
}

/// The notes every analysis starts with: the recording's source, how the FRF was estimated.
fn measurement_notes(rec: &Recording, measured: &EstimatedFrf) -> Vec<String> {
    let mut notes = Vec::new();
    if let Some(src) = &rec.sidecar.source {
        notes.push(format!("source: {src}"));
    }
    notes.push(measured.choices.clone());
    notes
}

/// An analysis of the measurement and its pairs, before any model is identified.
fn before_the_model(
    rec: &Recording,
    measured: EstimatedFrf,
    delay: u32,
    detection: Detection,
    notes: Vec<String>,
    supported: Option<[f64; 2]>,
    ground: Option<GroundDamperOut>,
) -> Analysis {
    Analysis {
        measured,
        sample_rate_hz: rec.sample_rate_hz,
        delay_samples: delay,
        total_inertia: None,
        detection,
        paper: None,
        exact: None,
        fit: None,
        orders: Vec::new(),
        model: None,
        model_frf: None,
        notes,
        time_cap: None,
        supported_band_hz: supported,
        ground_damper: ground,
    }
}

/// [`analyze`] from an FRF estimated beforehand from `rec` (and possibly corrected, e.g. a
/// known ground damper removed: `diagnose`'s damper-free starts). `rec` gives the sample
/// rate, the I/O delay and the sidecar's facts.
pub fn analyze_estimate(
    rec: &Recording,
    measured: EstimatedFrf,
    opts: &AnalysisOptions,
) -> Result<Analysis, AnalysisError> {
    let mut a = analyze_uncapped(rec, measured, opts)?;
    a.time_cap = super::TimeCap::of(&opts.fit.budget);
    if let Some(m) = a.time_cap.as_ref().and_then(|t| t.message()) {
        a.notes.insert(0, m);
    }
    Ok(a)
}

fn analyze_uncapped(
    rec: &Recording,
    measured: EstimatedFrf,
    opts: &AnalysisOptions,
) -> Result<Analysis, AnalysisError> {
    check_masses(opts)?;
    let fs = rec.sample_rate_hz;
    let delay = rec.sidecar.io_delay_samples.unwrap_or(0);
    let (mut analysis, work, fittable) = measure_and_detect(rec, measured, opts, delay)?;
    let total = total_inertia(
        rec,
        &work,
        &analysis.detection.pairs,
        delay,
        &mut analysis.notes,
    );
    let Some(total) = total else {
        return Ok(analysis);
    };
    let j = total.j_kgm2;
    analysis.total_inertia = Some(total);
    let spectra: Vec<(f64, f64)> = analysis
        .detection
        .pairs
        .iter()
        .map(|p| (p.ar_hz, p.r_hz))
        .collect();
    inverse_models(&mut analysis, j, &spectra);
    if !fittable {
        return Ok(analysis);
    }
    let pairs = Pairs::offered(j, &analysis.detection);
    let fit_opts = FitOptions {
        delay_samples: delay,
        band_hz: opts.band_hz.or(analysis.supported_band_hz),
        ..opts.fit.clone()
    };
    let fit = match opts.masses {
        Some(m) => fit_given_order(&mut analysis, m, &pairs, &fit_opts, opts)?,
        None => fit_chosen_order(&mut analysis, &pairs, &fit_opts, opts)?,
    };
    finish(analysis, fit, fs, delay)
}

/// `--masses` within 1 ..= max(max_masses, 8).
fn check_masses(opts: &AnalysisOptions) -> Result<(), AnalysisError> {
    match opts.masses {
        Some(m) if m == 0 || m > opts.max_masses.max(8) => Err(AnalysisError::Masses {
            masses: m,
            max: opts.max_masses.max(8),
        }),
        _ => Ok(()),
    }
}

/// The measured FRF and the anti-resonance/resonance pairs on it; also the mobility the
/// pairs are located on (the FRF itself, or its equivalent for a velocity or acceleration
/// response) and whether the chain can be fitted to the FRF (position or differenced
/// velocity response).
fn measure_and_detect(
    rec: &Recording,
    measured: EstimatedFrf,
    opts: &AnalysisOptions,
    delay: u32,
) -> Result<(Analysis, Frf, bool), AnalysisError> {
    let mut notes = measurement_notes(rec, &measured);
    let fittable = matches!(
        measured.frf.kind,
        FrfKind::DifferencedVelocity | FrfKind::Position
    );
    let ground = ground_damper::take_out(&measured.frf, delay).map(|(free_frf, damping)| {
        notes.push(format!(
            "viscous friction from the motor to the ground: b = {:.4e} +- {:.1e} N m s/rad on the lowest lines (Re of 1/mobility, {:.1} sigma): taken out of the measurement (Y / (1 - b Y)) before the pairs, the total inertia and the chain were identified, and put back into the model's FRF",
            damping.b_nms_per_rad,
            damping.std_nms_per_rad,
            damping.b_nms_per_rad / damping.std_nms_per_rad
        ));
        GroundDamperOut { damping, free_frf }
    });
    let work = if let Some(g) = &ground {
        if fittable {
            g.free_frf.clone()
        } else {
            mobility_equivalent(&g.free_frf)
        }
    } else if fittable {
        measured.frf.clone()
    } else {
        notes.push(match measured.frf.kind {
            FrfKind::Other => "the response is an acceleration: resonances are located on H/(j w); the chain fit needs a motor position or velocity".into(),
            _ => "the response is a recorded velocity, taken as the backward-differenced position for locating resonances; the chain fit needs the position".into(),
        });
        mobility_equivalent(&measured.frf)
    };
    let supported = supported_lines(&measured.frf, opts, &mut notes);
    let detect_opts = DetectOptions {
        delay_samples: delay,
        band_hz: opts.band_hz.or(supported),
        ..opts.detect.clone()
    };
    let detection = detect_pairs(&work, &detect_opts)?;
    notes.extend(detection.notes.iter().cloned());
    let analysis = before_the_model(rec, measured, delay, detection, notes, supported, ground);
    Ok((analysis, work, fittable))
}

/// The band the estimate supports when no band was given and its uncertainty leaves lines
/// out at either end; a note says where and why.
fn supported_lines(frf: &Frf, opts: &AnalysisOptions, notes: &mut Vec<String>) -> Option<[f64; 2]> {
    if opts.band_hz.is_some() {
        return None;
    }
    let sb = supported_band(frf)?;
    if !sb.trims() {
        return None;
    }
    notes.push(format!(
        "band used: {:.3} .. {:.3} Hz ({} of {} lines); outside it the response does not stand out of the estimate's own scatter (windowed SNR |H|/sigma below 2), so those lines carry no information and get no weight",
        sb.band_hz[0], sb.band_hz[1], sb.lines, sb.total_lines
    ));
    Some(sb.band_hz)
}

/// The chain of total inertia `j` [kg m^2] with exactly the anti-resonances and
/// resonances `sel` [Hz] (the Cauer inverse), couplings damped at 5 %.
fn exact_chain(j: f64, sel: &[(f64, f64)]) -> Option<Chain> {
    let ar: Vec<f64> = sel.iter().map(|p| p.0).collect();
    let r: Vec<f64> = sel.iter().map(|p| p.1).collect();
    chain_from_spectra(j, &ar, &r)
        .ok()
        .map(|c| with_coupling_damping(c, 0.05))
}

/// The paper's step-by-step inverse and the exact inverse of all detected pairs, and
/// how far apart they are.
fn inverse_models(analysis: &mut Analysis, j: f64, spectra: &[(f64, f64)]) {
    if !spectra.is_empty() {
        match step_by_step(j, spectra, None) {
            Ok(s) => analysis.paper = Some(s),
            Err(e) => analysis
                .notes
                .push(format!("step-by-step algorithm not applicable: {e}")),
        }
    }
    analysis.exact = exact_chain(j, spectra).map(|mut c| {
        c.damping_nms_per_rad.iter_mut().for_each(|d| *d = 0.0);
        c
    });
    if let (Some(p), Some(e)) = (&analysis.paper, &analysis.exact) {
        let worst = p
            .chain
            .inertia_kgm2
            .iter()
            .zip(&e.inertia_kgm2)
            .chain(
                p.chain
                    .stiffness_nm_per_rad
                    .iter()
                    .zip(&e.stiffness_nm_per_rad),
            )
            .map(|(a, b)| ((a - b) / b).abs())
            .fold(0.0, f64::max);
        analysis.notes.push(format!(
            "the step-by-step approximation differs from the exact inverse by up to {:.2} % (it treats each pair as an isolated two-body system)",
            100.0 * worst
        ));
    }
}

/// The pairs' indices, most prominent first (prominence: the smaller of the
/// anti-resonance's depth and the resonance's height).
fn by_prominence(pairs: &[ArRPair]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..pairs.len()).collect();
    order.sort_by(|&a, &b| {
        let pa = pairs[a].depth_db.min(pairs[a].height_db);
        let pb = pairs[b].depth_db.min(pairs[b].height_db);
        pb.total_cmp(&pa)
    });
    order
}

/// The pairs offered to the fit, as its initial chains are made from them: the detected
/// pairs first, then the unconfirmed ones (amplitude significant, phase rise short).
struct Pairs {
    /// Total inertia [kg m^2].
    j: f64,
    /// (anti-resonance, resonance) per pair [Hz]: the detected pairs in frequency order,
    /// then the unconfirmed ones.
    spectra: Vec<(f64, f64)>,
    /// Pair indices: the detected pairs most prominent first (in dB), then the unconfirmed
    /// ones most significant first (in sigma).
    by_prominence: Vec<usize>,
    /// How many of `spectra` are detected pairs.
    confirmed: usize,
    /// The pairs behind `spectra`, in the same order.
    offered: Vec<ArRPair>,
}

impl Pairs {
    /// The detected pairs and, most significant first (prominence in standard deviations:
    /// a noise notch can be deep in dB where the lines scatter), the unconfirmed pairs that
    /// interlace
    /// with them and with the more prominent unconfirmed ones kept before (a chain's
    /// pairs occupy disjoint intervals `[AR, R]`; one that overlaps a kept pair can never
    /// be part of the same chain).
    fn offered(j: f64, det: &Detection) -> Pairs {
        let confirmed = det.pairs.len();
        let mut offered: Vec<ArRPair> = det.pairs.clone();
        let mut order = by_prominence(&det.pairs);
        let mut by_sigma: Vec<usize> = (0..det.unconfirmed.len()).collect();
        by_sigma.sort_by(|&a, &b| {
            let s = |i: usize| det.unconfirmed[i].prominence_sigma;
            s(b).total_cmp(&s(a))
        });
        for i in by_sigma {
            let u = &det.unconfirmed[i];
            let disjoint = offered.iter().all(|p| u.r_hz < p.ar_hz || u.ar_hz > p.r_hz);
            if disjoint && u.ar_hz < u.r_hz {
                order.push(offered.len());
                offered.push(u.clone());
            }
        }
        Pairs {
            j,
            spectra: offered.iter().map(|p| (p.ar_hz, p.r_hz)).collect(),
            offered,
            by_prominence: order,
            confirmed,
        }
    }

    /// The `k` most prominent pairs, in frequency order, each with whether the detection
    /// confirmed it.
    fn selection(&self, k: usize) -> Vec<(&ArRPair, bool)> {
        let mut sel: Vec<(&ArRPair, bool)> = self.by_prominence[..k]
            .iter()
            .map(|&i| (&self.offered[i], i < self.confirmed))
            .collect();
        sel.sort_by(|a, b| a.0.ar_hz.total_cmp(&b.0.ar_hz));
        sel
    }

    /// The initial chain of `k > confirmed` pairs: the detected ones and the first choice
    /// of unconfirmed ones, most prominent first, that interlaces with them.
    fn completed_with_unconfirmed(&self, k: usize) -> Option<Chain> {
        let unconfirmed = &self.by_prominence[self.confirmed..];
        let need = k.checked_sub(self.confirmed).filter(|n| *n > 0)?;
        combinations(unconfirmed.len(), need, 32)
            .into_iter()
            .find_map(|choice| {
                let mut sel: Vec<(f64, f64)> = self.spectra[..self.confirmed]
                    .iter()
                    .copied()
                    .chain(choice.iter().map(|&c| self.spectra[unconfirmed[c]]))
                    .collect();
                sel.sort_by(|a, b| a.0.total_cmp(&b.0));
                exact_chain(self.j, &sel)
            })
    }

    /// The initial chain with the `k` most prominent pairs (those of [`Pairs::selection`]).
    fn chain_with(&self, k: usize) -> Option<Chain> {
        let sel: Vec<(f64, f64)> = self
            .selection(k)
            .iter()
            .map(|(p, _)| (p.ar_hz, p.r_hz))
            .collect();
        exact_chain(self.j, &sel)
    }
}

/// `--masses m`: the chain of `m` bodies. With fewer bodies than detected pairs, which
/// pairs the best reduced chain keeps is not known beforehand (the most prominent pair
/// need not be the one that explains most of the band), so every choice of `m - 1` pairs
/// (at most a few dozen) is a start: each screened by one coarse fit ([`screened`]), the
/// best fitted with all starts, and the lowest cost wins; with more, the missing pairs
/// start near the top of the band.
fn fit_given_order(
    analysis: &mut Analysis,
    m: usize,
    pairs: &Pairs,
    fit_opts: &FitOptions,
    opts: &AnalysisOptions,
) -> Result<ChainFit, AnalysisError> {
    let (j, spectra) = (pairs.j, &pairs.spectra[..pairs.confirmed]);
    let k = m - 1;
    let init = if k < spectra.len() {
        let inits: Vec<Chain> = combinations(spectra.len(), k, 32)
            .into_iter()
            .filter_map(|keep| {
                let sel: Vec<(f64, f64)> = keep.iter().map(|&i| spectra[i]).collect();
                exact_chain(j, &sel)
            })
            .collect();
        let choices = inits.len();
        match fit_lowest_cost(analysis.fitted_frf(), inits, m, fit_opts, opts) {
            Some(Ok(f)) => {
                let how = if choices > SCREENED {
                    format!(
                        "screened by one coarse fit, the best {SCREENED} fitted from every start"
                    )
                } else {
                    "fitted".to_string()
                };
                analysis.notes.push(format!(
                    "{m} bodies asked for, {} pairs detected: every choice of {k} pairs ({choices}) was {how} and the best kept",
                    spectra.len(),
                ));
                return Ok(f);
            }
            Some(Err(e)) => return Err(e.into()),
            None => None,
        }
    } else if k == spectra.len() {
        pairs.chain_with(k)
    } else if let Some(init) = pairs.completed_with_unconfirmed(k) {
        analysis.notes.push(format!(
            "{m} bodies asked for, {} pairs detected: the most prominent pairs whose phase rise is short of a clean pair's (unconfirmed) complete the chain",
            spectra.len(),
        ));
        Some(init)
    } else {
        let spectra = &pairs.spectra[..];
        let top = analysis
            .fitted_frf()
            .freq_hz
            .last()
            .copied()
            .unwrap_or(analysis.sample_rate_hz / 4.0);
        let near_top = |mut sel: Vec<(f64, f64)>| {
            let mut f = top * 0.5;
            while sel.len() < k {
                sel.push((f, f * 1.3));
                f *= 1.5;
            }
            sel
        };
        let rejected = rejected_pairs(&analysis.detection, spectra);
        let with_rejected = (!rejected.is_empty()).then(|| {
            let mut sel = spectra.to_vec();
            sel.extend(rejected.iter().take(k - spectra.len()));
            sel.sort_by(|a, b| a.0.total_cmp(&b.0));
            near_top(sel)
        });
        analysis.notes.push(format!(
            "{m} bodies asked for but only {} anti-resonance/resonance pairs were detected: the missing pairs start near the top of the band{}",
            spectra.len(),
            if with_rejected.is_some() {
                ", and from the notch-peak pairs short of the significance threshold (the better fit kept)"
            } else {
                ""
            }
        ));
        let inits = std::iter::once(near_top(spectra.to_vec()))
            .chain(with_rejected)
            .filter_map(|sel| exact_chain(j, &sel));
        match fit_lowest_cost(analysis.fitted_frf(), inits, m, fit_opts, opts) {
            Some(r) => return Ok(r?),
            None => None,
        }
    };
    let init = init.ok_or(IdentifyError::InvalidArgument(
        "no initial chain could be formed from the detected pairs".into(),
    ))?;
    opts.fit.budget.begin_fit(m, opts.fit.starts);
    Ok(fit_chain(analysis.fitted_frf(), &init, fit_opts)?)
}

/// Each of the initial chains `inits` fitted (`m` bodies) and the lowest cost kept; the
/// last error when none fits, `None` without any chain. Once the time cap has passed and a
/// fit exists, the remaining chains are skipped.
fn fit_lowest_cost(
    frf: &Frf,
    inits: impl IntoIterator<Item = Chain>,
    m: usize,
    fit_opts: &FitOptions,
    opts: &AnalysisOptions,
) -> Option<Result<ChainFit, IdentifyError>> {
    let budget = &opts.fit.budget;
    let (mut best, mut last_err): (Option<ChainFit>, Option<IdentifyError>) = (None, None);
    let mut inits: Vec<Chain> = inits.into_iter().collect();
    if inits.len() > SCREENED {
        inits = screened(frf, inits, fit_opts, budget, &mut last_err);
    }
    for init in inits {
        if budget.expired() && best.is_some() {
            budget.skip_order();
            continue;
        }
        budget.begin_fit(m, opts.fit.starts);
        match fit_chain(frf, &init, fit_opts) {
            Ok(f) if best.as_ref().is_none_or(|b| f.cost < b.cost) => best = Some(f),
            Ok(_) => {}
            Err(e) => last_err = Some(e),
        }
    }
    match (best, last_err) {
        (Some(f), _) => Some(Ok(f)),
        (None, Some(e)) => Some(Err(e)),
        (None, None) => None,
    }
}

/// More initial chains than this are screened ([`screened`]) before the multi-start fits.
/// The budget of the search, not a tolerance: `SCREENED` multi-start fits, each of
/// `FitOptions::starts` starts, around the best single-start optima.
const SCREENED: usize = 3;

/// The `SCREENED` best of `inits` after the coarse phase of a single start from each
/// ([`coarse_fit`]), as their coarse optima: the many choices of pairs a requested order
/// leaves (28 for two of eight detected pairs) are each one start of the search, and the
/// multi-start fits go where those ended lowest. An init whose coarse fit fails is dropped
/// (its error kept in `last_err`).
fn screened(
    frf: &Frf,
    inits: Vec<Chain>,
    fit_opts: &FitOptions,
    budget: &crate::identify::fit::FitBudget,
    last_err: &mut Option<IdentifyError>,
) -> Vec<Chain> {
    let mut fits: Vec<(Chain, f64)> = Vec::with_capacity(inits.len());
    for init in &inits {
        if budget.expired() && !fits.is_empty() {
            break;
        }
        match coarse_fit(frf, init, fit_opts) {
            Ok(f) if f.1.is_finite() => fits.push(f),
            Ok(_) => {}
            Err(e) => *last_err = Some(e),
        }
    }
    fits.sort_by(|a, b| a.1.total_cmp(&b.1));
    fits.into_iter().take(SCREENED).map(|f| f.0).collect()
}

/// Notch-peak pairs among the rejected candidates (a rejected notch and the nearest
/// rejected peak above it, with no candidate between them), disjoint from the pairs in
/// `taken`, the most significant first (the weaker of the two's sigma): starts for the
/// pairs a requested order needs beyond the detected ones (stepped sines' sparse spots put
/// a true pair just short of the threshold: a notch and a peak at 4.6 sigma).
fn rejected_pairs(det: &Detection, taken: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut r: Vec<&RejectedCandidate> = det.rejected.iter().collect();
    r.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    let mut out: Vec<(f64, f64, f64)> = r
        .windows(2)
        .filter(|w| w[0].kind == ExtremumKind::Notch && w[1].kind == ExtremumKind::Peak)
        .map(|w| {
            (
                w[0].freq_hz,
                w[1].freq_hz,
                w[0].prominence_sigma.min(w[1].prominence_sigma),
            )
        })
        .filter(|&(ar, r, _)| taken.iter().all(|&(a, b)| r < a || ar > b))
        .collect();
    out.sort_by(|a, b| b.2.total_cmp(&a.2));
    out.into_iter().map(|(a, r, _)| (a, r)).collect()
}

/// No `--masses`: the orders with all pairs and with the one or two least prominent
/// dropped, the order chosen by [`select_order`]. When the pairs do not interlace into any
/// chain (e.g. a pair split by backlash), the rigid body is still a model, and the report
/// says why.
fn fit_chosen_order(
    analysis: &mut Analysis,
    pairs: &Pairs,
    fit_opts: &FitOptions,
    opts: &AnalysisOptions,
) -> Result<ChainFit, AnalysisError> {
    let (j, spectra) = (pairs.j, &pairs.spectra);
    // the detected pairs with up to two dropped or up to two unconfirmed ones added
    let hi = spectra
        .len()
        .min(pairs.confirmed + 2)
        .min(opts.max_masses.saturating_sub(1));
    let lo = pairs.confirmed.min(hi).saturating_sub(2);
    let (mut candidates, mut offered): (Vec<Chain>, Vec<Vec<(&ArRPair, bool)>>) = (lo..=hi)
        .filter_map(|k| Some((pairs.chain_with(k)?, pairs.selection(k))))
        .unzip();
    if candidates.is_empty() {
        analysis.notes.push(format!(
            "the {} detected pairs do not form a spring-mass chain (anti-resonances and resonances must interlace): only the rigid body is fitted",
            pairs.confirmed
        ));
        candidates.extend(exact_chain(j, &[]));
        offered.push(Vec::new());
    }
    let sel = select_confirmed_order(analysis.fitted_frf(), &candidates, fit_opts, |k, f| {
        moved_feature(&offered[k], &f.chain)
    })?;
    analysis.orders = sel.candidates;
    let extra = (sel.fit.chain.masses() - 1).saturating_sub(pairs.confirmed);
    if extra > 0 {
        analysis.notes.push(format!(
            "{extra} pair(s) whose phase rise is short of a clean pair's (listed as unconfirmed) are in the model: the information criterion on the weighted residual says the data need them"
        ));
    }
    Ok(sel.fit)
}

/// The identified model's response on the measured lines and the summary, into `analysis`.
fn finish(
    mut analysis: Analysis,
    fit: ChainFit,
    fs: f64,
    delay: u32,
) -> Result<Analysis, AnalysisError> {
    let sc = SampledChain::new(&fit.chain, fs, delay)?;
    let b = analysis
        .ground_damper
        .as_ref()
        .map_or(0.0, |g| g.damping.b_nms_per_rad);
    let mut model_frf = analysis.measured.frf.clone();
    for (i, f) in model_frf.freq_hz.iter().enumerate() {
        let free = match model_frf.kind {
            FrfKind::Position => sc.position_frf(*f),
            _ => sc.frf(*f),
        };
        model_frf.h[i] = if b > 0.0 {
            ground_damper::with_ground_damper(free, *f, model_frf.kind, fs, b, delay)
        } else {
            free
        };
        model_frf.var[i] = 0.0;
    }
    model_frf.coherence = None;
    let mut summary = ModelSummary::new(&fit, &sc);
    summary.ground_damping = analysis.ground_damper.as_ref().map(|g| g.damping);
    analysis.model = Some(summary);
    analysis.model_frf = Some(model_frf);
    analysis.fit = Some(fit);
    Ok(analysis)
}

fn total_inertia(
    rec: &Recording,
    frf: &Frf,
    pairs: &[ArRPair],
    delay: u32,
    notes: &mut Vec<String>,
) -> Option<TotalInertia> {
    let lo = frf.freq_hz.first().copied().unwrap_or(0.0);
    let hi = frf.freq_hz.last().copied().unwrap_or(0.0);
    let est = match estimate_inertia_below_pairs(frf, pairs, (lo * 4.0).min(hi), delay) {
        Ok(e) => Some(e),
        Err(e) => {
            notes.push(format!("total inertia from the low-frequency gain: {e}"));
            // fall back to the lowest decade of lines, flagged
            estimate_inertia(frf, [lo, (lo * 2.0).min(hi)], delay).ok().inspect(|_| {
                notes.push("total inertia taken from the lowest lines although a compliant pair lies below them: it is biased low".into());
            })
        }
    };
    if let Some(j) = rec.sidecar.total_inertia_kgm2 {
        if let Some(e) = &est {
            notes.push(format!(
                "total inertia given in the sidecar: {j:.6e} kg m^2 (the low-frequency gain says {:.6e} +- {:.1e})",
                e.j_kgm2, e.std_kgm2
            ));
        }
        return Some(TotalInertia {
            j_kgm2: j,
            std_kgm2: 0.0,
            source: "sidecar",
            estimate: est,
        });
    }
    est.map(|e| TotalInertia {
        j_kgm2: e.j_kgm2,
        std_kgm2: e.std_kgm2,
        source: "low_frequency_gain",
        estimate: Some(e),
    })
}

/// The first `limit` of the `k`-element subsets of `0..n`, in lexicographic order.
fn combinations(n: usize, k: usize, limit: usize) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    if k == 0 || k > n {
        return out;
    }
    let mut idx: Vec<usize> = (0..k).collect();
    loop {
        out.push(idx.clone());
        if out.len() >= limit {
            return out;
        }
        // the rightmost index that can still move right
        let Some(i) = (0..k).rev().find(|&i| idx[i] < n - k + i) else {
            return out;
        };
        idx[i] += 1;
        for j in i + 1..k {
            idx[j] = idx[j - 1] + 1;
        }
    }
}

/// Whether the fit moved an unconfirmed pair's anti-resonance or resonance out of its
/// cell: the log-frequency interval halfway to the neighbouring offered features (at the
/// ends, mirrored). An unconfirmed pair is offered because its amplitude is significant
/// where it was seen; a fit that moves it elsewhere uses it to fit lines where the
/// detection saw nothing significant, so the data do not confirm that order, and the
/// reason says where it went. Detected pairs are not checked: their significance does not
/// rest on the fit, which may correct a detection's pairing (and a reduced order moves
/// them to compromise between dropped ones); nor are features known only as a bound.
fn moved_feature(offered: &[(&ArRPair, bool)], fitted: &Chain) -> Option<String> {
    let (ar, r) = (fitted.antiresonances_hz(), fitted.resonances_hz());
    if ar.len() != offered.len() || r.len() != offered.len() {
        return Some(format!(
            "{} pairs offered, the fitted chain has {}",
            offered.len(),
            r.len()
        ));
    }
    // (offered frequency, fitted frequency, checked, name), in frequency order
    let mut features = Vec::with_capacity(2 * offered.len());
    for (k, (p, confirmed)) in offered.iter().enumerate() {
        features.push((
            p.ar_hz,
            ar[k],
            !confirmed && !p.ar_below_band,
            "anti-resonance",
        ));
        features.push((p.r_hz, r[k], !confirmed && !p.r_above_band, "resonance"));
    }
    let ln: Vec<f64> = features.iter().map(|f| f.0.ln()).collect();
    for (i, &(o, m, checked, name)) in features.iter().enumerate() {
        if !checked || ln.len() < 2 {
            continue;
        }
        let below = if i > 0 {
            ln[i] - ln[i - 1]
        } else {
            ln[1] - ln[0]
        };
        let above = if i + 1 < ln.len() {
            ln[i + 1] - ln[i]
        } else {
            below
        };
        let d = m.ln() - ln[i];
        if d < -0.5 * below || d > 0.5 * above {
            return Some(format!(
                "the fit moved the unconfirmed {name} offered at {o:.2} Hz to {m:.2} Hz, where no significant feature was seen"
            ));
        }
    }
    None
}

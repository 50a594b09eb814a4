//! Automatic detection of anti-resonance / resonance (AR/R) pairs on a measured FRF.
//!
//! Not peak picking: the detector works on the normalised response
//! `R(f) = H_meas(f) / H_rigid,J=1(f)` — the measurement divided by the exact sampled
//! response of a unit rigid inertia, so that hold, differencing and delay are removed and
//! `|R| = 1/J_eff(f)` (the inverse effective inertia) while `arg R` is the phase relative
//! to the rigid-body trend (-90 deg for a velocity response). For a passive chain `arg R`
//! lies in [0, 180] deg: near 0 where the motor behaves like an inertia, near +180 deg between
//! an anti-resonance and its resonance (spring-like).
//!
//! 1. Candidates are the notches and peaks of `ln |R|` whose prominence exceeds both
//!    `min_depth_db` and `min_sigma` standard deviations of the lines involved (from `var`).
//! 2. Candidates are paired in the order physics imposes, AR1 < R1 < AR2 < R2 ..., and a
//!    pair is accepted only if the phase rises by at least `min_phase_rise_deg` between
//!    the AR and the R (the signature of a compliant coupling).
//! 3. Each accepted pair is refined by a local second-order rational fit of `R` (zero =
//!    anti-resonance, pole = resonance) with standard deviations; if that fit fails, by a
//!    parabola through `ln |R|` versus `ln f` at the extremum.
//!
//! 4. Independently of the pairing, every peak of `ln |R|` that passed the significance test
//!    of step 1 is listed in [`Detection::peaks`]: on structures that are not a free chain
//!    driven and measured at the motor (a suspended airframe, a non-collocated sensor) the
//!    AR/R alternation and the +180 deg phase rise need not hold, yet the resonances are
//!    still the significant peaks.
//!
//! A resonance whose anti-resonance lies below the lowest line (the phase is already
//! spring-like at the start) is reported with `ar_below_band`; an anti-resonance whose
//! resonance lies above the highest line with `r_above_band`.

use super::error::IdentifyError;
use super::lines::{fallback_sigma, sigma_log, usable_lines, RigidReference};
use super::local_fit::fit_second_order;
use crate::frf::Frf;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

const DB: f64 = 20.0 / std::f64::consts::LN_10;

/// Options of [`detect_pairs`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectOptions {
    /// Whole samples of command delay in the measurement.
    pub delay_samples: u32,
    /// Only lines inside this band [Hz] are used; all when `None`.
    pub band_hz: Option<[f64; 2]>,
    /// Minimum notch depth / peak height (prominence) [dB].
    pub min_depth_db: f64,
    /// Minimum prominence in standard deviations of the lines involved.
    pub min_sigma: f64,
    /// Minimum phase rise between an anti-resonance and its resonance [deg].
    pub min_phase_rise_deg: f64,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            delay_samples: 0,
            band_hz: None,
            min_depth_db: 6.0,
            min_sigma: 5.0,
            min_phase_rise_deg: 120.0,
        }
    }
}

/// One detected anti-resonance / resonance pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArRPair {
    /// Anti-resonance frequency [Hz]. When `ar_below_band`, the lowest line used: an upper
    /// bound only.
    pub ar_hz: f64,
    /// Resonance frequency [Hz]. When `r_above_band`, the highest line used: a lower bound
    /// only.
    pub r_hz: f64,
    /// Standard deviation of `ar_hz` [Hz] (infinite when not observed).
    pub ar_std_hz: f64,
    /// Standard deviation of `r_hz` [Hz] (infinite when not observed).
    pub r_std_hz: f64,
    /// Phase rise of `H` between the anti-resonance and the resonance [deg] (about 180 for
    /// a lightly damped, well separated pair).
    pub phase_rise_deg: f64,
    /// Prominence of the notch [dB] (0 when not observed).
    pub depth_db: f64,
    /// Prominence of the peak [dB] (0 when not observed).
    pub height_db: f64,
    /// Significance of the pair: the smaller of the notch's and the peak's prominence in
    /// standard deviations of the lines involved (of the one observed, if only one is).
    #[serde(default)]
    pub prominence_sigma: f64,
    /// The anti-resonance lies below the lowest line: only the resonance was seen.
    pub ar_below_band: bool,
    /// The resonance lies above the highest line: only the anti-resonance was seen.
    pub r_above_band: bool,
}

/// Kind of extremum of `|H|`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExtremumKind {
    /// Local minimum (anti-resonance candidate).
    Notch,
    /// Local maximum (resonance candidate).
    Peak,
}

/// A candidate extremum that did not become (part of) a pair, with the reason.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RejectedCandidate {
    /// Frequency of the extremum line [Hz].
    pub freq_hz: f64,
    /// Notch or peak.
    pub kind: ExtremumKind,
    /// Its prominence [dB].
    pub prominence_db: f64,
    /// Its prominence in standard deviations.
    pub prominence_sigma: f64,
    /// Why it was not accepted.
    pub reason: String,
}

/// A significant resonance peak, found independently of the AR/R pairing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResonancePeak {
    /// Frequency [Hz]: the pair's refined resonance when `paired`, else the vertex of a
    /// parabola through `ln |R|` versus `ln f` at the peak line.
    pub freq_hz: f64,
    /// Standard deviation of `freq_hz` [Hz] (from the line variances).
    pub std_hz: f64,
    /// Prominence of the peak [dB].
    pub prominence_db: f64,
    /// Prominence in standard deviations of the lines involved.
    pub prominence_sigma: f64,
    /// The peak is the resonance of an accepted AR/R pair.
    pub paired: bool,
}

/// Result of [`detect_pairs`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Accepted pairs, ascending in frequency.
    pub pairs: Vec<ArRPair>,
    /// All peaks that pass the significance thresholds (`min_depth_db` and `min_sigma`),
    /// paired or not, ascending in frequency: the resonances of the structure whether or not
    /// it behaves as a free chain.
    #[serde(default)]
    pub peaks: Vec<ResonancePeak>,
    /// Notch/peak pairs whose amplitude passes the significance thresholds but whose phase
    /// does not rise by `min_phase_rise_deg` between them (a heavily damped pair, or two
    /// features only a few lines apart), refined like accepted pairs, ascending in
    /// frequency. Not pairs of the detection: the order selection offers them to the
    /// fit, which keeps one only when the information criterion on the weighted residual
    /// says the data need it.
    #[serde(default)]
    pub unconfirmed: Vec<ArRPair>,
    /// Candidates that were rejected (only those with a prominence above 1 dB and 3 sigma,
    /// so that plain noise does not fill the report).
    pub rejected: Vec<RejectedCandidate>,
    /// Human-readable remarks (e.g. an anti-resonance below the band).
    pub notes: Vec<String>,
}

/// The normalised response on the usable lines: frequency [Hz], `R = H/H_rigid,J=1`
/// [1/(kg m^2)], and the standard deviation of `ln|R|` and `arg R` [1, rad].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NormalizedResponse {
    /// Line frequencies [Hz].
    pub freq_hz: Vec<f64>,
    /// `R = H_meas / H_rigid,J=1` [1/(kg m^2)]: `1/|R|` is the effective inertia.
    pub r: Vec<Complex64>,
    /// Standard deviation of `ln |R|` and of `arg R` [1, rad] per line.
    pub sigma: Vec<f64>,
}

impl NormalizedResponse {
    /// Effective inertia `J_eff = 1/|R|` [kg m^2] per line.
    pub fn effective_inertia(&self) -> Vec<f64> {
        self.r.iter().map(|r| 1.0 / r.norm()).collect()
    }

    /// Phase relative to the rigid-body trend [deg], in (-90, 270].
    pub fn relative_phase_deg(&self) -> Vec<f64> {
        self.r.iter().map(|r| rel_phase(*r).to_degrees()).collect()
    }
}

/// Normalise `frf` by the exact sampled response of a unit rigid inertia.
pub fn normalized_response(
    frf: &Frf,
    band_hz: Option<[f64; 2]>,
    delay_samples: u32,
) -> Result<NormalizedResponse, IdentifyError> {
    let reference = RigidReference::new(frf, delay_samples)?;
    let idx = usable_lines(frf, band_hz);
    let fb = fallback_sigma(frf, &idx);
    Ok(NormalizedResponse {
        freq_hz: idx.iter().map(|&i| frf.freq_hz[i]).collect(),
        r: idx
            .iter()
            .map(|&i| frf.h[i] / reference.at(frf.freq_hz[i]))
            .collect(),
        sigma: idx.iter().map(|&i| sigma_log(frf, i, fb)).collect(),
    })
}

/// Phase of `r` in (-pi/2, 3pi/2].
fn rel_phase(r: Complex64) -> f64 {
    let p = r.arg();
    if p <= -std::f64::consts::FRAC_PI_2 {
        p + 2.0 * std::f64::consts::PI
    } else {
        p
    }
}

#[derive(Debug, Clone, Copy)]
struct Candidate {
    i: usize,
    kind: ExtremumKind,
    /// Prominence in ln units.
    prom: f64,
    sigma: f64,
}

/// In a chain's motor mobility anti-resonances and resonances interlace: every resonance has
/// an anti-resonance below it. A significant peak whose preceding candidate is not a notch
/// (or that has none) takes the most prominent weaker notch between the previous candidate
/// and itself, if one is at least `min_depth_db` deep and 3 sigma; the pairing step still
/// demands the phase rise, so this cannot make a pair out of noise alone.
fn promote_interlacing_notches(
    cands: &mut Vec<Candidate>,
    weak: &[Candidate],
    det: &mut Detection,
    f: &[f64],
) {
    let mut promoted = Vec::new();
    for (k, c) in cands.iter().enumerate() {
        if c.kind != ExtremumKind::Peak {
            continue;
        }
        let prev = k.checked_sub(1).map(|j| cands[j]);
        if prev.is_some_and(|p| p.kind == ExtremumKind::Notch) {
            continue;
        }
        let lo = prev.map_or(0, |p| p.i);
        if let Some(best) = weak
            .iter()
            .filter(|w| w.i > lo && w.i < c.i)
            .max_by(|a, b| (a.prom / a.sigma).total_cmp(&(b.prom / b.sigma)))
        {
            promoted.push(*best);
        }
    }
    for p in &promoted {
        det.rejected
            .retain(|r| !(r.kind == ExtremumKind::Notch && r.freq_hz == f[p.i]));
        det.notes.push(format!(
            "notch at {:.4} Hz ({:.1} dB, {:.1} sigma) taken as the anti-resonance of the \
             resonance above it although below the sigma threshold: anti-resonances and \
             resonances interlace",
            f[p.i],
            p.prom * DB,
            p.prom / p.sigma
        ));
    }
    cands.extend(promoted);
    cands.sort_by_key(|c| c.i);
}

/// Detect AR/R pairs on `frf` (differenced-velocity or position FRF).
pub fn detect_pairs(frf: &Frf, opts: &DetectOptions) -> Result<Detection, IdentifyError> {
    let nr = normalized_response(frf, opts.band_hz, opts.delay_samples)?;
    let m = nr.freq_hz.len();
    if m < 5 {
        return Err(IdentifyError::TooFewLines {
            what: "pair detection",
            usable: m,
            needed: 5,
        });
    }
    let mut p = Pairing {
        y: nr.r.iter().map(|r| r.norm().ln()).collect(),
        ph: nr.r.iter().map(|r| rel_phase(*r)).collect(),
        nr: &nr,
        min_rise: opts.min_phase_rise_deg.to_radians(),
        lower_bound: 0,
        paired_peaks: Vec::new(),
        det: Detection {
            pairs: Vec::new(),
            unconfirmed: Vec::new(),
            peaks: Vec::new(),
            rejected: Vec::new(),
            notes: Vec::new(),
        },
    };
    // 1. candidates
    let cands = p.candidates(opts);
    // 2. pairing in physical order
    p.pair_in_order(&cands, opts);
    // 4. all significant peaks, paired or not
    let peaks = p.significant_peaks(&cands);
    let mut det = p.det;
    det.peaks = peaks;
    det.peaks.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    det.pairs.sort_by(|a, b| a.r_hz.total_cmp(&b.r_hz));
    det.unconfirmed.sort_by(|a, b| a.r_hz.total_cmp(&b.r_hz));
    det.rejected.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    Ok(det)
}

/// The state of [`detect_pairs`] over one normalised response.
struct Pairing<'a> {
    nr: &'a NormalizedResponse,
    /// `ln |R|` per line.
    y: Vec<f64>,
    /// The relative phase per line [rad].
    ph: Vec<f64>,
    /// The phase rise that marks a compliant coupling [rad].
    min_rise: f64,
    /// First line index after the previous accepted pair.
    lower_bound: usize,
    /// (line, r_hz, r_std_hz) of the resonances in accepted pairs.
    paired_peaks: Vec<(usize, f64, f64)>,
    det: Detection,
}

impl Pairing<'_> {
    /// Step 1: the notches and peaks prominent enough in dB and in sigma, in line order;
    /// weaker ones are rejected with their reason (notches deep enough in dB but short of
    /// the sigma threshold are kept for the interlacing rule).
    fn candidates(&mut self, opts: &DetectOptions) -> Vec<Candidate> {
        let (y, f, s) = (&self.y, &self.nr.freq_hz, &self.nr.sigma);
        let det = &mut self.det;
        let mut cands = Vec::new();
        let mut weak_notches: Vec<Candidate> = Vec::new();
        for kind in [ExtremumKind::Notch, ExtremumKind::Peak] {
            let sign = if kind == ExtremumKind::Peak {
                1.0
            } else {
                -1.0
            };
            let v: Vec<f64> = y.iter().map(|x| sign * x).collect();
            let k = opts.min_sigma.max(1.0);
            for (i, prom, iref) in prominences(&v) {
                // Near a notch the relative scatter of |H| is large (the motor barely moves
                // there) and ln|H| +- sigma is no longer symmetric. Of the two points compared,
                // the lower one (the notch line itself, or a peak's reference line, which is
                // often the bottom of the preceding notch) is judged by its upper confidence
                // bound |H|(1 + k s): `ln(1 + k s)/k` per sigma, ~ s for small s. The higher
                // point keeps its plain sigma.
                let ucb = |s: f64| (1.0 + k * s).ln() / k;
                let (s_line, s_ref) = if kind == ExtremumKind::Notch {
                    (ucb(s[i]), s[iref])
                } else {
                    (s[i], ucb(s[iref]))
                };
                let sigma = (s_line * s_line + s_ref * s_ref).sqrt();
                let c = Candidate {
                    i,
                    kind,
                    prom,
                    sigma,
                };
                let db = prom * DB;
                if db >= opts.min_depth_db && prom >= opts.min_sigma * sigma {
                    cands.push(c);
                } else if db >= 1.0 && prom >= 3.0 * sigma {
                    if kind == ExtremumKind::Notch && db >= opts.min_depth_db {
                        weak_notches.push(c);
                    }
                    det.rejected
                        .push(reject(f, &c, weak_reason(db, prom / sigma, opts)));
                }
            }
        }
        cands.sort_by_key(|c| c.i);
        promote_interlacing_notches(&mut cands, &weak_notches, det, f);
        cands
    }

    /// Step 2: each anti-resonance paired with the resonance that follows it when the
    /// phase rises between them; an anti-resonance at the top of the band and a resonance
    /// at its bottom may pair with a partner outside it.
    fn pair_in_order(&mut self, cands: &[Candidate], opts: &DetectOptions) {
        let mut k = 0;
        while k < cands.len() {
            let c = cands[k];
            match c.kind {
                ExtremumKind::Notch => {
                    if self.pair_notch(cands, k, opts) {
                        k += 2;
                        continue;
                    }
                    k += 1;
                }
                ExtremumKind::Peak => {
                    self.pair_peak(cands, k);
                    k += 1;
                }
            }
        }
    }

    /// The notch `cands[k]`: paired with the next peak (true: both used), or at the top
    /// of the band, or rejected.
    fn pair_notch(&mut self, cands: &[Candidate], k: usize, opts: &DetectOptions) -> bool {
        let c = cands[k];
        let (nr, m, min_rise, lower_bound) =
            (self.nr, self.y.len(), self.min_rise, self.lower_bound);
        let (y, ph, f, s) = (&self.y, &self.ph, &nr.freq_hz, &nr.sigma);
        let det = &mut self.det;
        let next = cands.get(k + 1).copied();
        match next {
            Some(n) if n.kind == ExtremumKind::Peak => {
                let base = min_smoothed(ph, lower_bound, c.i);
                let top = max_smoothed(ph, c.i, n.i + 1);
                let rise = top - base;
                if rise >= min_rise {
                    let upper = cands.get(k + 2).map_or(m, |x| x.i);
                    let p = refine_pair(nr, y, Some(c), Some(n), lower_bound, upper, rise);
                    self.paired_peaks.push((n.i, p.r_hz, p.r_std_hz));
                    det.pairs.push(p);
                    self.lower_bound = n.i;
                    return true;
                }
                // the notch is significant or taken by the interlacing rule (at least 3
                // sigma, [`promote_interlacing_notches`]): a significant peak makes the pair
                // unconfirmed (sparse lines, a stepped sine's spots, sample the rise short:
                // A 50601's notch at 4.4 sigma, rise 114 deg to a peak at 6.9 sigma)
                if n.prom >= opts.min_sigma * n.sigma {
                    let upper = cands.get(k + 2).map_or(m, |x| x.i);
                    det.unconfirmed.push(refine_pair(
                        nr,
                        y,
                        Some(c),
                        Some(n),
                        lower_bound,
                        upper,
                        rise,
                    ));
                }
                det.rejected.push(reject(
                    f,
                    &c,
                    format!(
                        "phase rises only {:.0} deg up to the peak at {:.4} Hz \
                         (needs {:.0})",
                        rise.to_degrees(),
                        f[n.i],
                        opts.min_phase_rise_deg
                    ),
                ));
            }
            Some(_) => det.rejected.push(reject(
                f,
                &c,
                "followed by another notch without a resonance in between".into(),
            )),
            None => {
                // resonance above the band?
                let base = min_smoothed(ph, lower_bound, c.i);
                let top = max_smoothed(ph, c.i, m);
                let tail = median(&ph[m.saturating_sub(3)..m]);
                let rise = top - base;
                if let Some(peak) = edge_resonance(y, ph, s, c.i, base, min_rise) {
                    // the resonance is inside the band but too close to its top
                    // for a two-sided prominence
                    let rise = max_smoothed(ph, c.i, peak.i + 1) - base;
                    let p = refine_pair(nr, y, Some(c), Some(peak), lower_bound, m, rise);
                    det.notes.push(format!(
                        "resonance at {:.4} Hz: {} lines below the top of the band, \
                         its peak is judged on its lower side only",
                        p.r_hz,
                        m - 1 - peak.i
                    ));
                    self.paired_peaks.push((peak.i, p.r_hz, p.r_std_hz));
                    det.pairs.push(p);
                    self.lower_bound = peak.i;
                } else if rise >= min_rise && tail - base >= min_rise {
                    let p = refine_pair(nr, y, Some(c), None, lower_bound, m, rise);
                    det.notes.push(format!(
                        "anti-resonance at {:.4} Hz: its resonance lies above the \
                         highest line ({:.4} Hz)",
                        p.ar_hz,
                        f[m - 1]
                    ));
                    det.pairs.push(p);
                } else {
                    det.rejected.push(reject(
                        f,
                        &c,
                        "no resonance follows and the phase does not stay \
                         spring-like up to the end of the band"
                            .into(),
                    ));
                }
            }
        }
        false
    }

    /// The peak `cands[k]` not taken by a notch: the first resonance, paired with an
    /// anti-resonance below the band when the phase is spring-like from the first line;
    /// otherwise rejected.
    fn pair_peak(&mut self, cands: &[Candidate], k: usize) {
        let c = cands[k];
        let (nr, m, min_rise) = (self.nr, self.y.len(), self.min_rise);
        let (y, ph, f) = (&self.y, &self.ph, &nr.freq_hz);
        let det = &mut self.det;
        let first = det.pairs.is_empty() && self.lower_bound == 0;
        let head = median(&ph[..3.min(m)]);
        let top = max_smoothed(ph, 0, c.i + 1);
        if first && head >= min_rise && top >= min_rise {
            let upper = cands.get(k + 1).map_or(m, |x| x.i);
            let p = refine_pair(nr, y, None, Some(c), 0, upper, top);
            self.paired_peaks.push((c.i, p.r_hz, p.r_std_hz));
            det.notes.push(format!(
                "resonance at {:.4} Hz: its anti-resonance lies below the lowest \
                 line ({:.4} Hz); the phase is already spring-like there",
                p.r_hz, f[0]
            ));
            det.pairs.push(p);
            self.lower_bound = c.i;
        } else {
            det.rejected.push(reject(
                f,
                &c,
                "resonance without an anti-resonance below it".into(),
            ));
        }
    }

    /// Step 4: every significant resonance peak, paired or not (a paired one at its
    /// pair's refined frequency).
    fn significant_peaks(&self, cands: &[Candidate]) -> Vec<ResonancePeak> {
        let (y, f, s) = (&self.y, &self.nr.freq_hz, &self.nr.sigma);
        let paired_peaks = &self.paired_peaks;
        cands
            .iter()
            .filter(|c| c.kind == ExtremumKind::Peak)
            .map(|c| {
                let paired = paired_peaks.iter().find(|p| p.0 == c.i);
                let (freq_hz, std_hz) =
                    paired.map_or_else(|| parabola(f, y, c.i, 1.0, s), |p| (p.1, p.2));
                ResonancePeak {
                    freq_hz,
                    std_hz,
                    prominence_db: c.prom * DB,
                    prominence_sigma: c.prom / c.sigma,
                    paired: paired.is_some(),
                }
            })
            .collect()
    }
}

/// Why a notch or peak of `db` [dB] and `n_sigma` standard deviations is not a candidate,
/// naming only the test it failed: "7.6 dB below 6 dB" read as a contradiction when it was
/// the sigma test that failed.
fn weak_reason(db: f64, n_sigma: f64, opts: &DetectOptions) -> String {
    let deep = db >= opts.min_depth_db;
    let significant = n_sigma >= opts.min_sigma;
    match (deep, significant) {
        (true, false) => format!(
            "{db:.1} dB deep enough, but only {n_sigma:.1} standard deviations of the lines' scatter: needs {}",
            opts.min_sigma
        ),
        (false, true) => format!(
            "{n_sigma:.1} standard deviations, but only {db:.1} dB: needs {} dB",
            opts.min_depth_db
        ),
        _ => format!(
            "only {db:.1} dB and {n_sigma:.1} standard deviations: needs {} dB and {}",
            opts.min_depth_db, opts.min_sigma
        ),
    }
}

fn reject(f: &[f64], c: &Candidate, reason: String) -> RejectedCandidate {
    RejectedCandidate {
        freq_hz: f[c.i],
        kind: c.kind,
        prominence_db: c.prom * DB,
        prominence_sigma: c.prom / c.sigma,
        reason,
    }
}

/// Local maxima of `v` with their topographic prominence and the index of the reference
/// (key col) line: `(index, prominence, reference index)`.
fn prominences(v: &[f64]) -> Vec<(usize, f64, usize)> {
    let m = v.len();
    let mut out = Vec::new();
    for i in 1..m - 1 {
        if !(v[i] > v[i - 1] && v[i] >= v[i + 1]) {
            continue;
        }
        // left: lowest point before a higher one
        let (mut lmin, mut li) = (v[i], i);
        let mut j = i;
        while j > 0 {
            j -= 1;
            if v[j] > v[i] {
                break;
            }
            if v[j] < lmin {
                lmin = v[j];
                li = j;
            }
        }
        let (mut rmin, mut ri) = (v[i], i);
        let mut j = i;
        while j + 1 < m {
            j += 1;
            if v[j] > v[i] {
                break;
            }
            if v[j] < rmin {
                rmin = v[j];
                ri = j;
            }
        }
        let (base, bi) = if lmin > rmin { (lmin, li) } else { (rmin, ri) };
        out.push((i, v[i] - base, bi));
    }
    out
}

/// A resonance just below the top of the band, after the last notch `notch`: the highest
/// line of `ln |R|` above the notch, inside the band (not the last line), falling to the
/// band's end by at least 3 standard deviations, with the phase rising by `min_rise` from
/// `base` up to it. Such a peak has no two-sided prominence (the band ends on its upper
/// flank), yet the notch, the rise and the fall mark it; a level still rising at the top of
/// the band is a resonance above it (`r_above_band`) instead.
fn edge_resonance(
    y: &[f64],
    ph: &[f64],
    sigma: &[f64],
    notch: usize,
    base: f64,
    min_rise: f64,
) -> Option<Candidate> {
    let m = y.len();
    let (i, &top) = y
        .iter()
        .enumerate()
        .skip(notch + 1)
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    let last = m - 1;
    let fall_sigma = (sigma[i].powi(2) + sigma[last].powi(2)).sqrt();
    let fall = top - y[last];
    let rise = max_smoothed(ph, notch, i + 1) - base;
    (i < last && fall >= 3.0 * fall_sigma && rise >= min_rise).then_some(Candidate {
        i,
        kind: ExtremumKind::Peak,
        prom: top - y[notch],
        sigma: (sigma[i].powi(2) + sigma[notch].powi(2)).sqrt(),
    })
}

/// Three-point running median of `v[lo..hi]`, then its maximum.
fn max_smoothed(v: &[f64], lo: usize, hi: usize) -> f64 {
    (lo..hi.min(v.len()))
        .map(|i| med3(v, i))
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Three-point running median of `v[lo..=hi]`, then its minimum.
fn min_smoothed(v: &[f64], lo: usize, hi: usize) -> f64 {
    (lo..=hi.min(v.len() - 1))
        .map(|i| med3(v, i))
        .fold(f64::INFINITY, f64::min)
}

fn med3(v: &[f64], i: usize) -> f64 {
    let a = v[i.saturating_sub(1)];
    let b = v[i];
    let c = v[(i + 1).min(v.len() - 1)];
    a.max(b).min(a.min(b).max(c))
}

fn median(v: &[f64]) -> f64 {
    let mut w = v.to_vec();
    w.sort_by(|a, b| a.total_cmp(b));
    w[w.len() / 2]
}

/// Refine one pair: local rational fit on the lines between the neighbouring candidates
/// (limited to a factor of the pair's own span), parabola fallback.
fn refine_pair(
    nr: &NormalizedResponse,
    y: &[f64],
    ar: Option<Candidate>,
    r: Option<Candidate>,
    lo_idx: usize,
    hi_idx: usize,
    rise: f64,
) -> ArRPair {
    let f = &nr.freq_hz;
    let m = f.len();
    let fa = ar.map(|c| f[c.i]);
    let fr = r.map(|c| f[c.i]);
    let (f_lo_c, f_hi_c) = match (fa, fr) {
        (Some(a), Some(b)) => (a, b),
        (Some(a), None) => (a, f[m - 1]),
        (None, Some(b)) => (f[0], b),
        (None, None) => unreachable!("a pair has at least one extremum"),
    };
    let span = (f_hi_c / f_lo_c).max(1.05);
    // window: geometric mid-points to the neighbouring extrema, at most one span beyond
    let lo_f = if lo_idx > 0 {
        (f[lo_idx] * f_lo_c).sqrt().max(f_lo_c / span)
    } else {
        f[0].max(f_lo_c / span)
    };
    let hi_f = if hi_idx < m {
        (f[hi_idx] * f_hi_c).sqrt().min(f_hi_c * span)
    } else {
        f[m - 1].min(f_hi_c * span)
    };
    let win: Vec<usize> = (0..m).filter(|&i| f[i] >= lo_f && f[i] <= hi_f).collect();
    let fc = (f_lo_c * f_hi_c).sqrt();
    let local = fit_second_order(
        &win.iter().map(|&i| f[i]).collect::<Vec<_>>(),
        &win.iter().map(|&i| nr.r[i]).collect::<Vec<_>>(),
        &win.iter()
            .map(|&i| nr.sigma[i] * nr.r[i].norm())
            .collect::<Vec<_>>(),
        fc,
    );
    // the neighbouring extrema bound the pair: features interlace
    let (f_min, f_max) = (
        if lo_idx > 0 { f[lo_idx] } else { 0.0 },
        if hi_idx < m { f[hi_idx] } else { f64::INFINITY },
    );
    let accept = |v: Option<super::local_fit::Refined>, c: f64| {
        v.filter(|x| {
            x.hz.is_finite()
                && x.hz > f_min
                && x.hz < f_max
                && (x.hz / c).ln().abs() < 0.5 * span.ln().max(0.05)
        })
    };
    let mut pair = ArRPair {
        ar_hz: f[0],
        r_hz: f[m - 1],
        ar_std_hz: f64::INFINITY,
        r_std_hz: f64::INFINITY,
        phase_rise_deg: rise.to_degrees(),
        depth_db: 0.0,
        height_db: 0.0,
        prominence_sigma: ar
            .iter()
            .chain(r.iter())
            .map(|c| c.prom / c.sigma)
            .fold(f64::INFINITY, f64::min),
        ar_below_band: ar.is_none(),
        r_above_band: r.is_none(),
    };
    if let Some(c) = ar {
        let fit = accept(local.and_then(|l| l.zero), f[c.i]);
        let (hz, sd) = fit.map_or_else(
            || parabola(f, y, c.i, -1.0, &nr.sigma),
            |x| (x.hz, x.std_hz),
        );
        pair.ar_hz = hz;
        pair.ar_std_hz = sd;
        pair.depth_db = c.prom * DB;
    }
    if let Some(c) = r {
        let fit = accept(local.and_then(|l| l.pole), f[c.i]);
        let (hz, sd) =
            fit.map_or_else(|| parabola(f, y, c.i, 1.0, &nr.sigma), |x| (x.hz, x.std_hz));
        pair.r_hz = hz;
        pair.r_std_hz = sd;
        pair.height_db = c.prom * DB;
    }
    pair
}

/// Vertex of the parabola through `sign * y` versus `ln f` at lines `i-1, i, i+1`, with a
/// standard deviation from the line noise: `(f [Hz], std [Hz])`.
fn parabola(f: &[f64], y: &[f64], i: usize, sign: f64, sigma: &[f64]) -> (f64, f64) {
    if i == 0 || i + 1 >= f.len() {
        return (f[i], f64::INFINITY);
    }
    let x = |k: usize| f[k].ln();
    let vertex = |y0: f64, y1: f64, y2: f64| -> f64 {
        let (x0, x1, x2) = (x(i - 1), x(i), x(i + 1));
        let d0 = (y1 - y0) / (x1 - x0);
        let d1 = (y2 - y1) / (x2 - x1);
        let a = (d1 - d0) / (x2 - x0);
        if a >= 0.0 {
            return x1;
        }
        let v = 0.5 * (x0 + x1) - d0 / (2.0 * a);
        v.clamp(x0, x2)
    };
    let (y0, y1, y2) = (sign * y[i - 1], sign * y[i], sign * y[i + 1]);
    let v = vertex(y0, y1, y2);
    let mut var = 0.0;
    for (k, dy) in [(0usize, sigma[i - 1]), (1, sigma[i]), (2, sigma[i + 1])] {
        let mut p = [y0, y1, y2];
        p[k] += dy;
        var += (vertex(p[0], p[1], p[2]) - v).powi(2);
    }
    let hz = v.exp();
    // a vertex pinned to a line is only known to within the line spacing
    let spacing = 0.5 * (x(i + 1) - x(i - 1)) / 12f64.sqrt();
    let sd = if var > 0.0 { var.sqrt() } else { spacing };
    (hz, hz * sd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::FrfKind;

    const FS: f64 = 4000.0;

    /// Velocity response of two grounded modes (10 Hz and 30 Hz, 2 % damping) with residues
    /// of opposite sign, as a non-collocated sensor sees them: no anti-resonance between the
    /// modes, so the second resonance cannot be paired. Relative line std `rel`.
    fn non_collocated(rel: f64) -> Frf {
        let n = 400;
        let freq_hz: Vec<f64> = (0..n)
            .map(|k| 2.0 * 50f64.powf(k as f64 / (n - 1) as f64))
            .collect();
        let mode = |f: f64, fn_hz: f64| {
            let (w, wn) = (
                2.0 * std::f64::consts::PI * f,
                2.0 * std::f64::consts::PI * fn_hz,
            );
            Complex64::new(1.0, 0.0) / Complex64::new(wn * wn - w * w, 2.0 * 0.02 * wn * w)
        };
        let h: Vec<Complex64> = freq_hz
            .iter()
            .map(|&f| {
                let jw = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
                jw * (mode(f, 10.0) - 0.5 * mode(f, 30.0))
            })
            .collect();
        let var = h.iter().map(|x| (rel * x.norm()).powi(2)).collect();
        Frf {
            freq_hz,
            h,
            var,
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: FS,
        }
    }

    #[test]
    fn peaks_list_resonances_that_the_pairing_rejects() {
        let det = detect_pairs(&non_collocated(1e-3), &DetectOptions::default()).unwrap();
        assert_eq!(det.peaks.len(), 2, "{det:?}");
        for (p, want) in det.peaks.iter().zip([10.0, 30.0]) {
            assert!((p.freq_hz / want - 1.0).abs() < 0.01, "{p:?} vs {want} Hz");
            assert!(p.std_hz.is_finite() && p.prominence_db >= 6.0 && p.prominence_sigma >= 5.0);
        }
        // the 30 Hz resonance has no anti-resonance below it: it is not a pair ...
        assert!(!det.peaks[1].paired);
        assert!(det.pairs.iter().all(|p| (p.r_hz / 30.0 - 1.0).abs() > 0.05));
        // ... but the pairing reports it as rejected
        assert!(det
            .rejected
            .iter()
            .any(|r| r.kind == ExtremumKind::Peak && (r.freq_hz / 30.0 - 1.0).abs() < 0.02));
    }

    #[test]
    fn rejection_reasons_name_the_test_that_failed() {
        let o = DetectOptions::default();
        let r = weak_reason(7.6, 3.2, &o);
        assert!(
            r.contains("deep enough") && r.contains("3.2") && r.contains("needs 5"),
            "{r}"
        );
        assert!(!r.contains("below 6"), "{r}");
        let r = weak_reason(2.0, 9.0, &o);
        assert!(r.contains("only 2.0 dB") && r.contains("needs 6 dB"), "{r}");
        let r = weak_reason(2.0, 3.0, &o);
        assert!(r.contains("needs 6 dB and 5"), "{r}");
    }

    #[test]
    fn peaks_need_significance_from_the_line_variance() {
        // Same response, but each line uncertain by 200 %: no peak is significant.
        let det = detect_pairs(&non_collocated(2.0), &DetectOptions::default()).unwrap();
        assert!(det.peaks.is_empty(), "{:?}", det.peaks);
        assert!(det.pairs.is_empty(), "{:?}", det.pairs);
    }

    #[test]
    fn a_paired_peak_carries_the_refined_resonance() {
        let ch = crate::model::Chain::new(vec![2e-3, 6e-3], vec![400.0], vec![0.02]).unwrap();
        let sc = crate::model::SampledChain::new(&ch, FS, 0).unwrap();
        let freq_hz: Vec<f64> = (0..500)
            .map(|k| 2.0 * 500f64.powf(k as f64 / 499.0))
            .collect();
        let h: Vec<Complex64> = freq_hz.iter().map(|&f| sc.frf(f)).collect();
        let var = h.iter().map(|x| (1e-3 * x.norm()).powi(2)).collect();
        let frf = Frf {
            freq_hz,
            h,
            var,
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: FS,
        };
        let det = detect_pairs(&frf, &DetectOptions::default()).unwrap();
        assert_eq!(det.pairs.len(), 1, "{det:?}");
        assert_eq!(det.peaks.len(), 1, "{det:?}");
        assert!(det.peaks[0].paired);
        assert_eq!(det.peaks[0].freq_hz, det.pairs[0].r_hz);
        assert!((det.peaks[0].freq_hz / ch.resonances_hz()[0] - 1.0).abs() < 0.01);
    }

    /// The demo's SCARA shoulder (AR/R 2.9/5 Hz, 380/590 Hz) sampled at 1.5 kHz, lines every
    /// 0.25 Hz up to `top_hz`, 1 % relative line std.
    fn scara_to(top_hz: f64) -> Frf {
        let ch = crate::model::Chain::new(
            vec![3.614e-3, 5.098e-3, 17.188e-3],
            vec![2.906e4, 5.706],
            vec![0.47, 0.018],
        )
        .unwrap();
        let sc = crate::model::SampledChain::new(&ch, 1500.0, 0).unwrap();
        let freq_hz: Vec<f64> = (1..=(top_hz / 0.25) as usize)
            .map(|k| k as f64 * 0.25)
            .collect();
        let h: Vec<Complex64> = freq_hz.iter().map(|&f| sc.frf(f)).collect();
        let var = h.iter().map(|x| (1e-2 * x.norm()).powi(2)).collect();
        Frf {
            freq_hz,
            h,
            var,
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: 1500.0,
        }
    }

    #[test]
    fn a_resonance_just_below_the_top_of_the_band_is_paired() {
        // the band ends 10 Hz above the 590 Hz resonance: no two-sided peak
        let det = detect_pairs(&scara_to(600.0), &DetectOptions::default()).unwrap();
        assert_eq!(det.pairs.len(), 2, "{det:?}");
        let p = &det.pairs[1];
        assert!(!p.r_above_band, "{p:?}");
        assert!((p.r_hz / 590.0 - 1.0).abs() < 0.01, "{p:?}");
        assert!((p.ar_hz / 380.0 - 1.0).abs() < 0.03, "{p:?}");
        // the band ends below the resonance (the level still rising): a resonance above
        // the band, not a peak at its edge
        let det = detect_pairs(&scara_to(560.0), &DetectOptions::default()).unwrap();
        assert_eq!(det.pairs.len(), 2, "{det:?}");
        assert!(det.pairs[1].r_above_band, "{:?}", det.pairs[1]);
    }

    /// A pair seen on 40 log-spaced spots (a stepped sine's): the lines sample a phase rise
    /// short of 120 deg, and the notch line is noisy (the motor barely moves there), so
    /// the notch is below 5 sigma but taken by the interlacing rule. With the peak
    /// significant the pair is unconfirmed (offered to the fit), not only rejected.
    #[test]
    fn a_weak_notch_with_a_short_rise_before_a_significant_peak_is_unconfirmed() {
        // AR 159 Hz, R 225 Hz, damped enough that the spots see a rise of 114 deg
        let ch = crate::model::Chain::new(vec![1e-3, 1e-3], vec![1000.0], vec![0.1]).unwrap();
        let fs = 4000.0;
        let sc = crate::model::SampledChain::new(&ch, fs, 0).unwrap();
        let freq_hz: Vec<f64> = (0..40).map(|i| 1600f64.powf(i as f64 / 39.0)).collect();
        let h: Vec<Complex64> = freq_hz.iter().map(|&f| sc.frf(f)).collect();
        // the notch line: the deepest below the resonance
        let notch = (1..39)
            .filter(|&i| freq_hz[i] < 225.0)
            .min_by(|&a, &b| h[a].norm().total_cmp(&h[b].norm()))
            .unwrap();
        // 100 % scatter at the notch line: about 4 sigma, 1 % elsewhere
        let rel_notch = 1.0;
        let var: Vec<f64> = h
            .iter()
            .enumerate()
            .map(|(i, x)| ((if i == notch { rel_notch } else { 0.01 }) * x.norm()).powi(2))
            .collect();
        let frf = Frf {
            freq_hz,
            h,
            var,
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: fs,
        };
        let det = detect_pairs(&frf, &DetectOptions::default()).unwrap();
        assert!(det.pairs.is_empty(), "{:?}", det.pairs);
        let short = |r: &&RejectedCandidate| r.reason.starts_with("phase rises only");
        let notch = det
            .rejected
            .iter()
            .find(short)
            .expect("the short rise is named");
        assert!(notch.prominence_sigma < 5.0, "{notch:?}");
        assert_eq!(det.unconfirmed.len(), 1, "{:?}", det.rejected);
        let p = &det.unconfirmed[0];
        assert!(
            (p.ar_hz / 159.2 - 1.0).abs() < 0.1 && (p.r_hz / 225.1 - 1.0).abs() < 0.1,
            "{p:?}"
        );
    }
}

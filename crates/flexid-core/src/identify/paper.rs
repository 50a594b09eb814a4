//! The step-by-step algorithm of Gannel & Gannel (2024), "Understanding the structure and
//! parameters identification of compliant robot arms using frequency domain analysis".
//!
//! The paper's equations were printed as images; they are re-derived here from the two-body
//! compliant reducer it builds on. With `J_a` on the motor side of a coupling of stiffness
//! `c` and `J_b` beyond it, the motor mobility is
//!
//! ```text
//! V1/T = (J_b s^2 + c) / (s (J_a J_b s^2 + c (J_a + J_b)))
//! w_AR^2 = c / J_b,   w_R^2 = c (J_a + J_b) / (J_a J_b)
//! mismatch  m = (f_R / f_AR)^2 = (J_a + J_b) / J_a
//! increment L = 20 log10(m) dB   (the Bode magnitude rises by L across the pair)
//! ```
//!
//! For a chain of n bodies the pairs are taken from the lowest up. Below pair k the motor
//! sees the inertia `J_(k) = J1 + .. + J(n-k+1)`; across pair k body `n-k+1` is "switched
//! off", so `J1 + .. + J(n-k) = J_(k) / m_k`, `J(n-k+1) = J_(k) - J_(k)/m_k` and the
//! stiffness that couples it is `c(n-k) = J(n-k+1) w_AR,k^2`.
//!
//! This treats each pair as an isolated two-body system and is an approximation when the
//! pairs are not far apart; [`super::exact`] gives the chain whose spectra are exactly the
//! measured ones.

use crate::model::Chain;
use serde::Serialize;
use std::f64::consts::PI;

/// Errors of the step-by-step algorithm.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PaperError {
    #[error("total inertia {j_kgm2} kg m^2 must be positive and finite")]
    TotalInertia { j_kgm2: f64 },
    #[error(
        "pair {pair}: anti-resonance {ar_hz} Hz must be positive and below its resonance {r_hz} Hz"
    )]
    PairOrder { pair: usize, ar_hz: f64, r_hz: f64 },
    #[error("pair {pair}: amplitude increment {l_db} dB must be positive")]
    Increment { pair: usize, l_db: f64 },
    #[error("{got} amplitude increments given for {pairs} pairs")]
    IncrementCount { pairs: usize, got: usize },
}

/// One anti-resonance/resonance pair as the paper processes it (steps 2-6, 7-11).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairStep {
    /// 1-based pair number, lowest frequency first.
    pub pair: usize,
    pub ar_hz: f64,
    pub r_hz: f64,
    /// Mismatch ratio `(f_R/f_AR)^2` [-].
    pub mismatch: f64,
    /// Amplitude increment `L = 20 log10(mismatch)` [dB] implied by the frequencies.
    pub increment_db: f64,
    /// Increment actually used (read off a plot when given, else `increment_db`) [dB].
    pub increment_used_db: f64,
    /// Inertia seen below the pair, `J1 + .. + J(n-k+1)` [kg m^2].
    pub inertia_below_kgm2: f64,
    /// Inertia that stays coupled to the motor above the pair, `J1 + .. + J(n-k)` [kg m^2].
    pub inertia_above_kgm2: f64,
    /// The body switched off across the pair: its 1-based index and inertia [kg m^2].
    pub body: usize,
    pub body_inertia_kgm2: f64,
    /// The coupling that causes the pair: 1-based index i (between bodies i and i+1) and its
    /// stiffness [N m/rad].
    pub coupling: usize,
    pub stiffness_nm_per_rad: f64,
}

/// Result of the step-by-step algorithm.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepByStep {
    pub total_inertia_kgm2: f64,
    pub pairs: Vec<PairStep>,
    /// The resulting chain (dampings not identified by this method: zero).
    pub chain: Chain,
}

/// Paper step 1 (from a Bode plot of the complete plant): total inertia from the plant gain
/// `gain_db` read at 1 rad/s of a plant `K_A K_T K_E / (J s)` (current amplifier gain
/// `ka` [A/bit], torque constant `kt` [N m/A], feedback gain `ke` [counts/rad], speed output):
/// `J = K_A K_T K_E / 10^(gain_db/20)` [kg m^2].
pub fn total_inertia_from_gain(gain_db: f64, ka: f64, kt: f64, ke: f64) -> f64 {
    ka * kt * ke / 10f64.powf(gain_db / 20.0)
}

/// Amplitude increment [dB] between two inertia levels: `20 log10(j_below / j_above)`.
pub fn increment_db(j_below: f64, j_above: f64) -> f64 {
    20.0 * (j_below / j_above).log10()
}

/// Run the step-by-step algorithm on `pairs` = `[(f_AR, f_R)]` [Hz] (any order; sorted
/// ascending here) for a chain of `pairs.len() + 1` bodies of total inertia `total_j`.
///
/// `increments_db`: amplitude increments read off the plot, one per pair, to use instead of
/// the ones implied by the frequencies (the paper reads them off its Figure 1).
pub fn step_by_step(
    total_j: f64,
    pairs: &[(f64, f64)],
    increments_db: Option<&[f64]>,
) -> Result<StepByStep, PaperError> {
    if !(total_j.is_finite() && total_j > 0.0) {
        return Err(PaperError::TotalInertia { j_kgm2: total_j });
    }
    let mut sorted: Vec<(f64, f64)> = pairs.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    if let Some(l) = increments_db {
        if l.len() != sorted.len() {
            return Err(PaperError::IncrementCount {
                pairs: sorted.len(),
                got: l.len(),
            });
        }
    }
    let n = sorted.len() + 1;
    let mut inertia = vec![0.0; n];
    let mut stiffness = vec![0.0; n - 1];
    let mut steps = Vec::with_capacity(n - 1);
    let mut j_below = total_j;
    for (k, &(ar, r)) in sorted.iter().enumerate() {
        if !(ar > 0.0 && r > ar && r.is_finite()) {
            return Err(PaperError::PairOrder {
                pair: k + 1,
                ar_hz: ar,
                r_hz: r,
            });
        }
        let mismatch = (r / ar).powi(2);
        let l_freq = 20.0 * mismatch.log10();
        let l_used = increments_db.map_or(l_freq, |l| l[k]);
        if !(l_used > 0.0 && l_used.is_finite()) {
            return Err(PaperError::Increment {
                pair: k + 1,
                l_db: l_used,
            });
        }
        let j_above = j_below / 10f64.powf(l_used / 20.0);
        let body = n - k; // 1-based index of the body switched off
        let j_body = j_below - j_above;
        let w_ar = 2.0 * PI * ar;
        let c = j_body * w_ar * w_ar;
        inertia[body - 1] = j_body;
        stiffness[body - 2] = c;
        steps.push(PairStep {
            pair: k + 1,
            ar_hz: ar,
            r_hz: r,
            mismatch,
            increment_db: l_freq,
            increment_used_db: l_used,
            inertia_below_kgm2: j_below,
            inertia_above_kgm2: j_above,
            body,
            body_inertia_kgm2: j_body,
            coupling: body - 1,
            stiffness_nm_per_rad: c,
        });
        j_below = j_above;
    }
    inertia[0] = j_below;
    Ok(StepByStep {
        total_inertia_kgm2: total_j,
        pairs: steps,
        chain: Chain {
            inertia_kgm2: inertia,
            stiffness_nm_per_rad: stiffness,
            damping_nms_per_rad: vec![0.0; n - 1],
        },
    })
}

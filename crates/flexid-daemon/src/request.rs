//! The body of `POST /api/v1/axes/{axis}/sweeps`: parsed field by field (so every error
//! names its field), validated against the axis's limits and planned into the exact torque
//! sequence. Nothing here touches the backend.

use super::backend::SweepPlan;
use super::config::AxisConfig;
use flexid_core::excitation::{
    band_lines, AmplitudeShape, ChirpDesign, ExcitationInfo, ExcitationKind, MultisineDesign,
    PhaseDesign,
};
use serde_json::{Map, Value};

/// Most periods a sweep may have.
pub const MAX_PERIODS: usize = 1000;

/// A refused request: 400 (not JSON / not an object) or 422 (a field is wrong).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct RequestError {
    /// HTTP status: 400 or 422.
    pub status: u16,
    /// The offending field, if one.
    pub field: Option<String>,
    pub message: String,
}

impl RequestError {
    fn syntax(message: impl Into<String>) -> Self {
        RequestError {
            status: 400,
            field: None,
            message: message.into(),
        }
    }
    fn field(field: &str, message: impl Into<String>) -> Self {
        RequestError {
            status: 422,
            field: Some(field.into()),
            message: format!("{field}: {}", message.into()),
        }
    }
}

/// The excitation signal of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExcitationChoice {
    /// Periodic multisine, amplitude rising with frequency (level velocity response).
    Multisine,
    /// Logarithmic swept sine, repeated once per period.
    Chirp,
}

/// A validated sweep request.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SweepRequest {
    pub excitation: ExcitationChoice,
    /// Excited band `[lo, hi]` [Hz], `0 < lo < hi < cycle_hz / 2`.
    pub band_hz: [f64; 2],
    /// Peak torque of the excitation [N m], `0 < a <= limits.peak_torque_nm`.
    pub amplitude_nm: f64,
    /// Measured (steady-state) periods, 1..=[`MAX_PERIODS`]; one transient period is added.
    pub periods: usize,
    /// Total duration [s] including the transient period, `0 < t <= limits.max_sweep_s`.
    pub duration_s: f64,
    /// A two-level sweep: the peak torques `[low, high]` [N m] (`0 < low < high <= peak`).
    /// The same excitation runs at the low then the high level (each a complete sweep),
    /// then the gap diagnosis runs on the pair ([`flexid_core::diagnose`]). `amplitude_nm` is then
    /// the high level.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub levels_nm: Option<[f64; 2]>,
    /// Bodies of the diagnosis's nominal chain (1..=8; two-level sweeps only). Default: the
    /// number the identification of the high level found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub masses: Option<usize>,
}

/// Seed of the odd random-phase multisine of two-level sweeps (the same signal every time).
pub const TWO_LEVEL_SEED: u64 = 0x2_1e7e1;

const FIELDS: [&str; 7] = [
    "excitation",
    "band_hz",
    "amplitude_nm",
    "periods",
    "duration_s",
    "levels_nm",
    "masses",
];

/// Parse and validate a request body for `axis`.
pub fn parse_request(body: &[u8], axis: &AxisConfig) -> Result<SweepRequest, RequestError> {
    let v: Value = serde_json::from_slice(body)
        .map_err(|e| RequestError::syntax(format!("the body is not valid JSON: {e}")))?;
    let Value::Object(obj) = v else {
        return Err(RequestError::syntax("the body must be a JSON object"));
    };
    if let Some(k) = obj.keys().find(|k| !FIELDS.contains(&k.as_str())) {
        return Err(RequestError::field(k, "unknown field"));
    }
    let excitation = match obj.get("excitation") {
        None => return Err(RequestError::field("excitation", "missing")),
        Some(Value::String(s)) if s == "multisine" => ExcitationChoice::Multisine,
        Some(Value::String(s)) if s == "chirp" => ExcitationChoice::Chirp,
        Some(_) => {
            return Err(RequestError::field(
                "excitation",
                "must be \"multisine\" or \"chirp\"",
            ))
        }
    };
    let band = pair(&obj, "band_hz")?.ok_or_else(|| RequestError::field("band_hz", "missing"))?;
    let levels_nm = pair(&obj, "levels_nm")?;
    // with levels, the amplitude is the high level (it may be omitted)
    let amplitude_nm = match (obj.get("amplitude_nm"), levels_nm) {
        (None, Some(l)) => l[1],
        _ => number(&obj, "amplitude_nm")?,
    };
    let periods = match obj.get("periods") {
        None => return Err(RequestError::field("periods", "missing")),
        Some(v) => match v.as_u64() {
            Some(n) if (1..=MAX_PERIODS as u64).contains(&n) => n as usize,
            _ => {
                return Err(RequestError::field(
                    "periods",
                    format!("must be an integer 1..={MAX_PERIODS}"),
                ))
            }
        },
    };
    let duration_s = number(&obj, "duration_s")?;
    let masses = match obj.get("masses") {
        None | Some(Value::Null) => None,
        Some(v) => match v.as_u64() {
            Some(n) if (1..=8).contains(&n) => Some(n as usize),
            _ => return Err(RequestError::field("masses", "must be an integer 1..=8")),
        },
    };
    if masses.is_some() && levels_nm.is_none() {
        return Err(RequestError::field(
            "masses",
            "only for a two-level sweep (give levels_nm)",
        ));
    }

    let nyq = axis.nyquist_hz();
    let lim = &axis.limits;
    if !(band[0] > 0.0 && band[1] > band[0]) {
        return Err(RequestError::field("band_hz", "need 0 < lo < hi"));
    }
    if band[1] >= nyq {
        return Err(RequestError::field(
            "band_hz",
            format!(
                "{} Hz is not below the Nyquist frequency {nyq} Hz of axis {} ({} Hz cycle)",
                band[1], axis.name, axis.cycle_hz
            ),
        ));
    }
    if let Some(l) = levels_nm {
        if !l.iter().all(|&a| a > 0.0 && a <= lim.peak_torque_nm) {
            return Err(RequestError::field(
                "levels_nm",
                format!(
                    "each level must be > 0 and at most the peak torque limit {} N m",
                    lim.peak_torque_nm
                ),
            ));
        }
        if l[0] >= l[1] {
            return Err(RequestError::field(
                "levels_nm",
                "need [low, high] with low < high",
            ));
        }
        if amplitude_nm != l[1] {
            return Err(RequestError::field(
                "amplitude_nm",
                format!(
                    "a two-level sweep runs at levels_nm; amplitude_nm, when given, must be \
                     the high level {} N m",
                    l[1]
                ),
            ));
        }
    }
    if amplitude_nm <= 0.0 {
        return Err(RequestError::field("amplitude_nm", "must be > 0"));
    }
    if amplitude_nm > lim.peak_torque_nm {
        return Err(RequestError::field(
            "amplitude_nm",
            format!(
                "{amplitude_nm} N m is above the peak torque limit {} N m of axis {}",
                lim.peak_torque_nm, axis.name
            ),
        ));
    }
    if duration_s <= 0.0 {
        return Err(RequestError::field("duration_s", "must be > 0"));
    }
    if duration_s > lim.max_sweep_s {
        return Err(RequestError::field(
            "duration_s",
            format!(
                "{duration_s} s is above the longest sweep {} s of axis {}",
                lim.max_sweep_s, axis.name
            ),
        ));
    }
    Ok(SweepRequest {
        excitation,
        band_hz: band,
        amplitude_nm,
        periods,
        duration_s,
        levels_nm,
        masses,
    })
}

fn number(obj: &Map<String, Value>, field: &str) -> Result<f64, RequestError> {
    match obj.get(field) {
        None => Err(RequestError::field(field, "missing")),
        Some(v) => v
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| RequestError::field(field, "must be a number")),
    }
}

fn pair(obj: &Map<String, Value>, field: &str) -> Result<Option<[f64; 2]>, RequestError> {
    match obj.get(field) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::Array(a)) if a.len() == 2 => match (a[0].as_f64(), a[1].as_f64()) {
            (Some(x), Some(y)) if x.is_finite() && y.is_finite() => Ok(Some([x, y])),
            _ => Err(RequestError::field(field, "must be two numbers")),
        },
        Some(_) => Err(RequestError::field(
            field,
            "must be an array of two numbers",
        )),
    }
}

/// Plan the torque sequence of a validated request: one transient period plus `periods`
/// measured ones, each `duration_s / (periods + 1)` long. Errors (422) name the field that
/// makes the plan impossible (e.g. a band below the line spacing).
pub fn plan(
    req: &SweepRequest,
    axis: &AxisConfig,
    sweep_id: &str,
) -> Result<SweepPlan, RequestError> {
    let fs = axis.cycle_hz;
    let total = req.periods + 1;
    let period_samples = (req.duration_s * fs / total as f64).floor() as usize;
    if period_samples < 16 {
        return Err(RequestError::field(
            "duration_s",
            format!(
                "too short for {} periods at {fs} Hz (each period needs at least 16 cycles)",
                req.periods
            ),
        ));
    }
    let lines = band_lines(fs, period_samples, req.band_hz).map_err(|e| {
        RequestError::field(
            "band_hz",
            format!(
                "{e} (line spacing {:.4} Hz: lengthen duration_s or lower periods)",
                fs / period_samples as f64
            ),
        )
    })?;
    let (period, mut info) = match req.excitation {
        ExcitationChoice::Multisine => {
            let mut d = MultisineDesign::new(
                fs,
                period_samples,
                req.band_hz,
                req.amplitude_nm,
                req.amplitude_nm,
            );
            d.crest_iterations = 10;
            d.amplitude = AmplitudeShape::PowerLaw { exponent: 1.0 };
            if req.levels_nm.is_some() {
                // detection lines: the diagnosis sees odd nonlinear distortion there
                d.phases = PhaseDesign::OddRandom {
                    seed: TWO_LEVEL_SEED,
                    group: 3,
                };
            }
            let ms = d
                .generate()
                .map_err(|e| RequestError::field("band_hz", e.to_string()))?;
            let info = ms.info(req.periods, 1);
            (ms.period, info)
        }
        ExcitationChoice::Chirp => {
            let period_s = period_samples as f64 / fs;
            let mut d = ChirpDesign::new(
                fs,
                req.band_hz[0],
                req.band_hz[1],
                period_s,
                req.amplitude_nm,
            );
            d.taper_s = (0.05 * period_s).min(0.5);
            let c = d
                .generate()
                .map_err(|e| RequestError::field("band_hz", e.to_string()))?;
            let mut p = c.signal;
            p.resize(period_samples, 0.0);
            let info = ExcitationInfo {
                kind: ExcitationKind::Chirp,
                period_samples,
                periods: req.periods,
                transient_periods: 1,
                excited_lines: lines,
                band_hz: Some(req.band_hz),
                peak_nm: Some(flexid_core::excitation::peak_abs(&p)),
                rms_nm: Some(flexid_core::excitation::rms(&p)),
                design: Some("periodic_log_sweep".into()),
                blocks: Vec::new(),
                realisations: Vec::new(),
                band_limited: false,
            };
            (p, info)
        }
    };
    // the limit is a hard bound: clip rounding excursions of the scaling
    let peak = req.amplitude_nm.min(axis.limits.peak_torque_nm);
    let period: Vec<f64> = period.iter().map(|x| x.clamp(-peak, peak)).collect();
    info.peak_nm = Some(flexid_core::excitation::peak_abs(&period));
    Ok(SweepPlan {
        sweep_id: sweep_id.to_string(),
        sample_rate_hz: fs,
        torque_nm: period.repeat(total),
        info,
        levels_nm: req.levels_nm,
    })
}

/// The plans of a two-level sweep: the excitation planned at the high level, and the same
/// signal scaled to the low level (its info's peak and RMS rescaled). One plan when the
/// request has no levels.
pub fn plan_levels(
    req: &SweepRequest,
    axis: &AxisConfig,
    sweep_id: &str,
) -> Result<Vec<SweepPlan>, RequestError> {
    let Some([low, high]) = req.levels_nm else {
        return Ok(vec![plan(req, axis, sweep_id)?]);
    };
    let hi_req = SweepRequest {
        amplitude_nm: high,
        ..req.clone()
    };
    let hi = plan(&hi_req, axis, sweep_id)?;
    let scale = low / high;
    let mut lo = hi.clone();
    lo.torque_nm.iter_mut().for_each(|x| *x *= scale);
    lo.info.peak_nm = lo.info.peak_nm.map(|p| p * scale);
    lo.info.rms_nm = lo.info.rms_nm.map(|r| r * scale);
    Ok(vec![lo, hi])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{ClockKind, Limits};

    fn axis() -> AxisConfig {
        AxisConfig {
            name: "j1".into(),
            bus: "can0".into(),
            node: 1,
            profile: None,
            cycle_hz: 2000.0,
            clock: ClockKind::Simulated,
            limits: Limits {
                peak_torque_nm: 2.0,
                max_speed_rad_s: 50.0,
                position_window_rad: 10.0,
                max_sweep_s: 60.0,
                max_lost_tpdos: None,
            },
        }
    }

    fn req(s: &str) -> Result<SweepRequest, RequestError> {
        parse_request(s.as_bytes(), &axis())
    }

    #[test]
    fn errors_name_the_field() {
        let ok = r#"{"excitation":"multisine","band_hz":[1,400],"amplitude_nm":1,"periods":4,"duration_s":5}"#;
        assert!(req(ok).is_ok());
        let e = req(&ok.replace("\"amplitude_nm\":1", "\"amplitude_nm\":\"big\"")).unwrap_err();
        assert_eq!((e.status, e.field.as_deref()), (422, Some("amplitude_nm")));
        let e = req(&ok.replace("400]", "1000]")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("band_hz"));
        let e = req(&ok.replace("\"amplitude_nm\":1", "\"amplitude_nm\":3")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("amplitude_nm"));
        let e = req("{nope").unwrap_err();
        assert_eq!(e.status, 400);
        let e = req(&ok.replace("\"periods\":4", "\"periods\":4,\"x\":1")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("x"));
        let e = req(&ok.replace("\"periods\":4", "\"periods\":-4")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("periods"));
    }

    #[test]
    fn plan_respects_the_limit() {
        for ex in ["multisine", "chirp"] {
            let r = req(&format!(
                r#"{{"excitation":"{ex}","band_hz":[2,300],"amplitude_nm":1.5,"periods":3,"duration_s":4}}"#
            ))
            .unwrap();
            let p = plan(&r, &axis(), "x").unwrap();
            assert_eq!(p.torque_nm.len(), 4 * p.info.period_samples);
            assert!(p.torque_nm.iter().all(|x| x.abs() <= 1.5));
            assert!(!p.info.excited_lines.is_empty());
        }
    }

    #[test]
    fn two_level_plans_scale_one_signal() {
        let r = req(r#"{"excitation":"multisine","band_hz":[2,300],"levels_nm":[0.4,1.6],"periods":3,"duration_s":4}"#)
            .unwrap();
        assert_eq!(r.amplitude_nm, 1.6, "the amplitude is the high level");
        let p = plan_levels(&r, &axis(), "x").unwrap();
        assert_eq!(p.len(), 2);
        let peak = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!((peak(&p[1].torque_nm) - 1.6).abs() < 1e-9);
        assert!((peak(&p[0].torque_nm) - 0.4).abs() < 1e-9);
        // the same signal: the low level is the high one scaled, sample by sample
        for (lo, hi) in p[0].torque_nm.iter().zip(&p[1].torque_nm) {
            assert!((lo * 4.0 - hi).abs() < 1e-12);
        }
        assert_eq!(p[0].info.excited_lines, p[1].info.excited_lines);
        assert_eq!(p[1].info.design.as_deref(), Some("odd_random_phase"));
        assert!((p[0].info.peak_nm.unwrap() - 0.4).abs() < 1e-9);
        // one plan without levels
        let one = req(r#"{"excitation":"chirp","band_hz":[2,300],"amplitude_nm":1,"periods":3,"duration_s":4}"#)
            .unwrap();
        assert_eq!(plan_levels(&one, &axis(), "x").unwrap().len(), 1);
        let e = req(r#"{"excitation":"multisine","band_hz":[2,300],"levels_nm":[1,1],"periods":3,"duration_s":4}"#)
            .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("levels_nm"));
        let e = req(r#"{"excitation":"multisine","band_hz":[2,300],"levels_nm":[0.1,3],"periods":3,"duration_s":4}"#)
            .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("levels_nm"));
    }
}

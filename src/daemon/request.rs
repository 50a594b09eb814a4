//! The body of `POST /api/v1/axes/{axis}/sweeps`: parsed field by field (so every error
//! names its field), validated against the axis's limits and planned into the exact torque
//! sequence. Nothing here touches the backend.

use super::backend::SweepPlan;
use super::config::AxisConfig;
use crate::excitation::{
    band_lines, AmplitudeShape, ChirpDesign, ExcitationInfo, ExcitationKind, MultisineDesign,
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
    /// Two amplitude levels [N m] for a later gap diagnosis (each `0 < a <= peak`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub levels_nm: Option<[f64; 2]>,
}

const FIELDS: [&str; 6] = [
    "excitation",
    "band_hz",
    "amplitude_nm",
    "periods",
    "duration_s",
    "levels_nm",
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
    let amplitude_nm = number(&obj, "amplitude_nm")?;
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
    let levels_nm = pair(&obj, "levels_nm")?;

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
    }
    Ok(SweepRequest {
        excitation,
        band_hz: band,
        amplitude_nm,
        periods,
        duration_s,
        levels_nm,
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
                peak_nm: Some(crate::excitation::peak_abs(&p)),
                rms_nm: Some(crate::excitation::rms(&p)),
                design: Some("periodic_log_sweep".into()),
            };
            (p, info)
        }
    };
    // the limit is a hard bound: clip rounding excursions of the scaling
    let peak = req.amplitude_nm.min(axis.limits.peak_torque_nm);
    let period: Vec<f64> = period.iter().map(|x| x.clamp(-peak, peak)).collect();
    info.peak_nm = Some(crate::excitation::peak_abs(&period));
    Ok(SweepPlan {
        sweep_id: sweep_id.to_string(),
        sample_rate_hz: fs,
        torque_nm: period.repeat(total),
        info,
        levels_nm: req.levels_nm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::daemon::config::{ClockKind, Limits};

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
}

//! The diagnosis as JSON (the contract: `verdict`, `effects[{effect, after_rms_db, score,
//! params}]`, `gap.{before_rms_db, after_rms_db,
//! bands[{lo_hz, hi_hz, excess_db}]}`, `ranking[{effect, after_rms_db, score}]`).

use super::Diagnosis;
use serde_json::{json, Value};

fn num(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

pub fn to_json(d: &Diagnosis) -> Value {
    let g = &d.gap;
    let chain = &d.nominal.lin.chain;
    json!({
        "verdict": d.verdict,
        "effects": d.effects.iter().map(|s| json!({
            "effect": s.effect, "after_rms_db": num(s.after_rms_db), "score": num(s.score),
            "params": s.fit.params.iter().map(|p| json!({"name": p.name, "value": num(p.value), "std": num(p.std)})).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "masses": d.masses,
        "gap": {
            "before_rms_db": num(g.before_rms_db),
            "after_rms_db": num(g.after_rms_db),
            "before_raw_rms_db": num(g.before_raw_rms_db),
            "after_raw_rms_db": num(g.after_raw_rms_db),
            "before_magnitude_rms_db": num(g.before_mag_db),
            "after_magnitude_rms_db": num(g.after_mag_db),
            "before_phase_rms_deg": num(g.before_phase_deg),
            "after_phase_rms_deg": num(g.after_phase_deg),
            "noise_rms_db": num(g.noise_rms_db),
            "bands": g.bands.iter().map(|(b, after)| json!({
                "level": b.level, "lo_hz": b.lo_hz, "hi_hz": b.hi_hz, "lines": b.lines,
                "peak_hz": num(b.peak_hz), "core_lo_hz": num(b.core_lo_hz), "core_hi_hz": num(b.core_hi_hz),
                "shape": b.shape,
                "excess_db": num(b.excess_db), "excess_deg": num(b.excess_deg),
                "mean_z2": num(b.mean_z2),
                "magnitude_significant": b.magnitude_significant,
                "phase_significant": b.phase_significant,
                "after_rms_db": num(*after),
            })).collect::<Vec<_>>(),
        },
        "ranking": d.ranking.iter().map(|r| json!({
            "effect": r.effect, "after_rms_db": num(r.after_rms_db), "score": num(r.score),
            "chi2": num(r.chi2), "added_params": r.added_params,
            "params": r.params.iter().map(|p| json!({"name": p.name, "value": num(p.value), "std": num(p.std)})).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "effect_params": d.winner.as_ref().map(|w| w.params.iter().map(|p| json!({"name": p.name, "value": num(p.value), "std": num(p.std)})).collect::<Vec<_>>()),
        "residual": {
            "reduced_chi2": num(d.residual.reduced_chi2),
            "within_noise": d.residual.within_noise,
            "nonlinear_distortion": d.residual.nonlinear,
            "linear_model_error": d.residual.linear_model_error,
            "levels": d.residual.levels.iter().map(|l| json!({
                "level": l.level, "torque_rms_nm": num(l.torque_rms_nm),
                "detection_excess_db": l.detection_excess_db.map(num),
                "detection_lines_hit": l.detection_lines_hit.map(num),
                "distortion_hz": l.distortion_hz.map(|w| [num(w[0]), num(w[1])]),
            })).collect::<Vec<_>>(),
            "level_changes": d.residual.changes.iter().map(|c| json!({
                "a": c.a, "b": c.b, "mean_z2": num(c.mean_z2), "rms_db": num(c.rms_db), "significant": c.significant,
            })).collect::<Vec<_>>(),
        },
        "nominal": {
            "inertia_kgm2": chain.inertia_kgm2,
            "stiffness_nm_per_rad": chain.stiffness_nm_per_rad,
            "damping_nms_per_rad": chain.damping_nms_per_rad,
        },
        "notes": d.notes,
        "seconds": num(d.seconds),
    })
}

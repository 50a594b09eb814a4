use super::Analysis;
use serde_json::{json, Value};

/// The analysis as the JSON document of `flexid identify --json` (a stable contract):
/// `{"model": {"masses", "inertia_kgm2", "stiffness_nm_per_rad", "resonance_hz",
/// "antiresonance_hz", ...}, "total_inertia", "pairs", "resonance_peaks_hz",
/// "resonance_peaks", "paper", "exact", "fit", "orders",
/// "frf", "notes", "time_cap"}`; `time_cap` is `null` without a cap, else
/// `{"max_seconds", "capped", "elapsed_s", "starts_skipped", "orders_skipped"}` (`capped`:
/// the model is the best found before the cap). `model` is `null` when no chain could be fitted (e.g. acceleration data).
/// `resonance_peaks_hz` lists every significant peak whether or not it is part of an AR/R
/// pair (structures that are not a free chain: suspended airframes, non-collocated sensors).
pub fn to_json(a: &Analysis) -> Value {
    let f = &a.measured.frf;
    json!({
        "model": a.model,
        "total_inertia": a.total_inertia,
        "pairs": a.detection.pairs,
        "unconfirmed_pairs": a.detection.unconfirmed,
        "resonance_peaks_hz": a.detection.peaks.iter().map(|p| p.freq_hz).collect::<Vec<_>>(),
        "resonance_peaks": a.detection.peaks,
        "rejected_candidates": a.detection.rejected,
        "paper": a.paper,
        "exact": a.exact,
        "fit": a.fit.as_ref().map(|fit| json!({
            "starts": fit.starts,
            "starts_converged": fit.starts_converged,
            "chi2_per_dof": fit.chi2_per_dof,
            "cost": fit.cost,
            "lines_used": fit.lines_used,
            "residual_rms_db": fit.residual_rms_db,
            "residual_rms_deg": fit.residual_rms_deg,
        })),
        "orders": a.orders,
        "supported_band_hz": a.supported_band_hz,
        "frf": {
            "method": a.measured.method,
            "averages": a.measured.averages,
            "kind": f.kind,
            "sample_rate_hz": a.sample_rate_hz,
            "delay_samples": a.delay_samples,
            "lines": f.len(),
            "band_hz": [f.freq_hz.first(), f.freq_hz.last()],
        },
        "notes": a.notes,
        "time_cap": a.time_cap,
    })
}

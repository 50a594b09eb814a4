//! Viscous friction from the motor to the ground as part of the *nominal* model (not an
//! effect): every real axis has some (bearings, seals, the motor's own losses), and a
//! nominal chain without it leaves a gap at low frequency that the first candidate bringing
//! a ground damper (gravity) would take. Kept only when the data say it is there: the cost
//! falls by more than the parameter's BIC price `ln(lines)`, and the damping is
//! significantly above zero (at least 3 standard deviations, its uncertainty scaled by the
//! reduced chi-square where that exceeds 1). Otherwise it is zero.

use super::{fit_best_start, log_std, model_on, Lin};
use crate::diagnose::lti::LinExt;
use crate::diagnose::Data;

/// Significance of a parameter that must differ from zero [standard deviations]: the
/// one-sided probability that noise alone reaches it is 0.13 %.
pub const SIGNIFICANT_SIGMA: f64 = 3.0;

/// The nominal model with or without viscous friction to the ground, and a note saying
/// which and why.
pub fn nominal_with_viscous(data: &Data, nominal: &LinExt) -> (LinExt, String) {
    let jt = nominal.chain.total_inertia();
    let w0 = 2.0 * std::f64::consts::PI * data.f_min().max(1e-3);
    let starts: Vec<LinExt> = [0.003, 0.03, 0.3, 3.0]
        .iter()
        .map(|r| {
            let mut s = nominal.clone();
            s.motor_b = r * jt * w0;
            s
        })
        .collect();
    let Some((m, r)) = fit_best_start(data, Lin::Viscous, &starts, 40, 2) else {
        return (
            nominal.clone(),
            "viscous friction to the ground: could not be fitted; the nominal model has none"
                .into(),
        );
    };
    let lines = data.lines().max(1) as f64;
    let chi2 = |l: &LinExt| data.chi2(&model_on(l, data.fs, data.kind, &data.full_targets));
    let (c0, c1) = (chi2(nominal), chi2(&m));
    let n = m.chain.masses();
    let std = log_std(&r, 3 * n - 2, m.motor_b) * (c1 / lines).max(1.0).sqrt();
    let z = m.motor_b / std;
    let significant = c0 - c1 > lines.ln() && std.is_finite() && z >= SIGNIFICANT_SIGMA;
    let words = if std.is_finite() {
        format!(
            "viscous friction motor-ground b = {:.3e} +- {:.1e} N m s/rad ({:.1} sigma; chi2 {:.4e} -> {:.4e})",
            m.motor_b, std, z, c0, c1
        )
    } else {
        format!(
            "viscous friction motor-ground b = {:.3e} N m s/rad, uncertainty undefined (chi2 {:.4e} -> {:.4e})",
            m.motor_b, c0, c1
        )
    };
    if significant {
        (
            m,
            format!("{words}: significant, part of the nominal model"),
        )
    } else {
        (
            nominal.clone(),
            format!("{words}: not significant, the nominal model has none"),
        )
    }
}

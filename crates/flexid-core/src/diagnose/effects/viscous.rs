//! Viscous friction from the motor to the ground as part of the *nominal* model (not an
//! effect): every real axis has some (bearings, seals, the motor's own losses), and a
//! nominal chain without it leaves a gap at low frequency that the first candidate bringing
//! a ground damper (gravity) would take. Kept only when the data say it is there: the cost
//! falls by more than the parameter's BIC price `ln(lines)`, and the damping is
//! significantly above zero (at least 3 standard deviations). Its uncertainty is scaled by
//! the reduced chi-square of the lines where the damping has leverage (the sandwich
//! estimator for one parameter), not of the whole band: a large gap elsewhere (a delay at
//! the top of the band) must not hide a damping the low lines clearly show. Otherwise it
//! is zero.

use super::{fit_best_start, log_std, model_on, Lin};
use crate::diagnose::lti::LinExt;
use crate::diagnose::Data;

pub use crate::diagnose::noise::SIGNIFICANT_SIGMA;

/// The outcome of [`nominal_with_viscous`].
pub struct ViscousNominal {
    /// The nominal model: with viscous friction when it is significant.
    pub nominal: LinExt,
    /// The fit with viscous friction, significant or not (`None`: it could not be
    /// fitted), and its chi².
    pub with_viscous: Option<(LinExt, f64)>,
    /// Whether `nominal` carries the viscous friction.
    pub significant: bool,
    /// What was found, for the notes.
    pub note: String,
}

/// The nominal model with or without viscous friction to the ground, and a note saying
/// which and why. Started from the nominal chain and from the identifications `idents`
/// (the chains the nominal fit started from): a nominal chain fitted without the damper
/// can have bent into a basin (a soft extra pair mimicking the ground damping) that the
/// damper alone does not leave. `fitted`: models with the damper to start from as they
/// are (a better nominal model found by a candidate's fit, the chain identified with the
/// damper taken out of the measurement: [`crate::diagnose::damper_free`]).
pub fn nominal_with_viscous(
    data: &Data,
    nominal: &LinExt,
    fitted: &[LinExt],
    idents: &[crate::model::Chain],
) -> ViscousNominal {
    let jt = nominal.chain.total_inertia();
    let w0 = 2.0 * std::f64::consts::PI * data.f_min().max(1e-3);
    let mut starts: Vec<LinExt> = Vec::new();
    for base in std::iter::once(nominal.clone()).chain(idents.iter().map(|c| LinExt {
        chain: c.clone(),
        ..nominal.clone()
    })) {
        for r in [0.003, 0.03, 0.3, 3.0] {
            let mut s = base.clone();
            s.motor_b = r * jt * w0;
            starts.push(s);
        }
    }
    starts.extend(fitted.iter().filter(|f| f.motor_b > 0.0).cloned());
    let Some((m, r)) = fit_best_start(data, Lin::Viscous, &starts, 40, 2) else {
        return ViscousNominal {
            nominal: nominal.clone(),
            with_viscous: None,
            significant: false,
            note: "viscous friction to the ground: could not be fitted; the nominal model has none"
                .into(),
        };
    };
    let lines = data.lines().max(1) as f64;
    let (c0, c1) = (data.chi2_of(nominal), data.chi2_of(&m));
    let excess = leverage_weighted_excess(data, &m);
    let std = log_std(&r, super::nominal_params(&m, Lin::Viscous), m.motor_b) * excess.sqrt();
    // significance by the likelihood ratio with the local dispersion (quasi-likelihood):
    // z² = (chi²_without - chi²_with) / dispersion where the damper acts. The Wald form
    // b/std can say 0.2 sigma for a damper that removes 60 % of chi² (a current-loop plant
    // on the viscous benchmark): the log-parameter's curvature at the optimum says little
    // when the chain moves with it.
    let z = ((c0 - c1).max(0.0) / (excess * data.noise.mean)).sqrt();
    let significant = (c0 - c1) / data.noise.mean > lines.ln() && z >= SIGNIFICANT_SIGMA;
    // a covariance's sigma larger than the value says the chain moves with it, not a
    // number to print (2.4e-1 +- 2.7e6 beside 22 sigma by the likelihood ratio)
    let words = if std.is_finite() && std <= m.motor_b.abs() {
        format!(
            "viscous friction motor-ground b = {:.3e} +- {:.1e} N m s/rad ({:.1} sigma by the likelihood ratio; chi2 {:.4e} -> {:.4e})",
            m.motor_b, std, z, c0, c1
        )
    } else {
        format!(
            "viscous friction motor-ground b = {:.3e} N m s/rad, its covariance's uncertainty undefined or larger than the value ({:.1} sigma by the likelihood ratio; chi2 {:.4e} -> {:.4e})",
            m.motor_b, z, c0, c1
        )
    };
    let note = if significant {
        format!("{words}: significant, part of the nominal model")
    } else {
        format!("{words}: not significant on its own, the nominal model has none (the linear candidates are also tried with it)")
    };
    ViscousNominal {
        nominal: if significant {
            m.clone()
        } else {
            nominal.clone()
        },
        with_viscous: Some((m, c1)),
        significant,
        note,
    }
}

/// The sandwich (heteroscedasticity-consistent) variance of `ln b` over its classical one,
/// at least 1: `sum g_i^2 z_i^2 / sum g_i^2`, with `g_i` the weighted change of line `i`
/// under a small change of `ln b` and `z_i^2` the line's weighted residual. Equal to the
/// reduced chi-square when the residual is uniform; the residual where the damping does
/// not act does not count.
fn leverage_weighted_excess(data: &Data, m: &LinExt) -> f64 {
    let eps = 1e-3;
    let mut moved = m.clone();
    moved.motor_b *= 1.0 + eps;
    let m0 = model_on(m, data.fs, data.kind, &data.full_targets);
    let m1 = model_on(&moved, data.fs, data.kind, &data.full_targets);
    let (mut num, mut den) = (0.0, 0.0);
    for ((l, a), b) in data.levels.iter().zip(&m0).zip(&m1) {
        let z = crate::diagnose::localise::z2(&l.h, &l.var, a);
        let g = crate::diagnose::localise::z2(a, &l.var, b);
        for (zi, gi) in z.iter().zip(&g) {
            if zi.is_finite() && gi.is_finite() {
                num += gi * zi;
                den += gi;
            }
        }
    }
    if den > 0.0 {
        (num / den).max(1.0)
    } else {
        1.0
    }
}

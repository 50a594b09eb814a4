//! The trajectory identification as a [`Diagnosis`]: what is named, the gap, the ranking.
//!
//! * **Coulomb friction** (`coulomb_friction`) is named only when `Fc` is at least 3
//!   standard deviations from zero **and** adding it to the viscous model lowers the
//!   residual by more than its BIC price (`N ln(RSS_viscous / RSS_friction) > ln N`).
//! * **Viscous friction** is not an effect of its own: it is a parameter of the model with
//!   its standard deviation, kept when it passes the same two tests over the rigid body
//!   (the first note says which).
//! * Otherwise the verdict is `none` when the model kept (the rigid body, with viscous
//!   friction if significant) leaves a residual within the noise the floors predict
//!   ([`TrajectoryFit::within_noise`]), else `unexplained`.
//!
//! **The gap** of this path is the force residual of the rigid body **without friction**
//! (before) and of the model **with the friction kept** (after), expressed like the
//! frequency-domain gap: a relative error `e` is `|ln(1 + e)| ~ e` nepers, so
//! `gap_db = 8.69 · ||residual|| / ||F(tau)||` (0.0869 dB per percent of relative force
//! error). `before_rms_db` / `after_rms_db` are systematic (the predicted noise removed:
//! `sqrt(max(0, RSS - N noise²)) / ||F(tau)||`), the `raw` ones include the noise. There
//! are no frequency bands (`gap.bands` is empty), no magnitude or phase parts (null).

use super::{idim, Kept, TrajectoryError, TrajectoryFit};
use crate::diagnose::effects::{EffectFit, Param};
use crate::diagnose::localise::DB_PER_NEPER;
use crate::diagnose::lti::LinExt;
use crate::diagnose::noise::NoiseChi2;
use crate::diagnose::rank::Ranked;
use crate::diagnose::{
    Data, DiagnoseError, DiagnoseOptions, Diagnosis, Effect, Gap, ResidualKind, Step,
};
use crate::frf::FrfKind;
use crate::recording::Recording;

/// Whether [`crate::diagnose::diagnose`] takes the trajectory path: a one-body model
/// (`masses == 1`) and no recording with a designed excitation (a multisine, a sweep or a
/// stepped sine has an FRF; a trajectory, kind `other` or undescribed, does not).
pub fn applies(recs: &[Recording], masses: usize) -> bool {
    masses == 1
        && !recs.is_empty()
        && recs.iter().all(|r| {
            r.sidecar
                .excitation
                .as_ref()
                .is_none_or(|e| e.kind == crate::excitation::ExcitationKind::Other)
        })
}

/// The systematic and raw gap [dB] and the reduced chi² of a model.
fn gap_db(t: &TrajectoryFit, fit: &idim::LsFit) -> (f64, f64) {
    let noise2 = fit.samples as f64 * t.noise_rms_nm.powi(2);
    let y = t.force_norm_nm;
    (
        DB_PER_NEPER * (fit.rss - noise2).max(0.0).sqrt() / y,
        DB_PER_NEPER * fit.rss.sqrt() / y,
    )
}

fn params(fit: &idim::LsFit, order: &[idim::Column]) -> Vec<Param> {
    order
        .iter()
        .filter_map(|&c| {
            fit.param(c)
                .map(|(v, sd)| EffectFit::param(c.name(), v, sd))
        })
        .collect()
}

/// A model as an [`EffectFit`]: the parameters (the defining one first), the chain of
/// one body with the fitted inertia, the viscous friction as the motor's ground damping.
fn effect_fit(
    t: &TrajectoryFit,
    fit: &idim::LsFit,
    effect: Effect,
    added: usize,
) -> Result<EffectFit, DiagnoseError> {
    let m = fit.value(idim::Column::Inertia);
    let chain = crate::model::Chain::new(vec![m], vec![], vec![])
        .map_err(|_| DiagnoseError::Trajectory(0, TrajectoryError::NegativeInertia(m)))?;
    let mut lin = LinExt::nominal(chain);
    lin.motor_b = fit.value(idim::Column::Viscous);
    Ok(EffectFit {
        effect,
        params: params(
            fit,
            &[
                idim::Column::Coulomb,
                idim::Column::Viscous,
                idim::Column::Inertia,
                idim::Column::Offset,
            ],
        ),
        added,
        chi2: fit.rss / t.noise_rms_nm.powi(2),
        model: Vec::new(),
        lin,
    })
}

fn ranked(t: &TrajectoryFit, f: &EffectFit, fit: &idim::LsFit, score: f64) -> Ranked {
    Ranked {
        effect: f.effect,
        after_rms_db: gap_db(t, fit).0,
        score,
        chi2: f.chi2,
        added_params: f.added,
        params: f.params.clone(),
    }
}

fn pct(x: f64) -> f64 {
    100.0 * x
}

fn notes(t: &TrajectoryFit, recs: &[Recording], opts: &DiagnoseOptions) -> Vec<String> {
    let (fv, sfv) = t
        .rigid_viscous
        .param(idim::Column::Viscous)
        .unwrap_or((f64::NAN, f64::NAN));
    let (fc, sfc) = t
        .rigid_friction
        .param(idim::Column::Coulomb)
        .unwrap_or((f64::NAN, f64::NAN));
    let c = &t.cutoff;
    let p = &t.processing;
    let mut n = vec![
        format!(
            "viscous friction {}: Fv = {fv:.4e} +- {sfv:.2e} N m s/rad ({:.1} sigma; BIC score {:.1} over the rigid body)",
            if t.viscous_significant { "kept" } else { "not significant" },
            t.viscous_sigmas,
            t.viscous_score
        ),
        format!(
            "trajectory path (the recording is not periodic and the model is one body): inverse dynamic identification model, least squares (IDIM-LS) of tau = M qdd + Fv qd + Fc sign(qd) + offset, no frequency response estimated"
        ),
        format!(
            "cut-off {:.2} Hz from the data: where the position's spectrum (smoothed over 1/3 octave) falls to twice its white-noise floor {:.3e} rad^2/Hz (median over {:.0}-{:.0} Hz){}; 4th-order Butterworth forward and backward on the position, the force and sign(qd); central differences; one sample in {}, {} edge samples dropped",
            c.cutoff_hz,
            c.position_floor_rad2_per_hz,
            c.floor_band_hz[0],
            c.floor_band_hz[1],
            if c.capped { " (never below it under the floor band: capped at the band's edge)" } else { "" },
            p.decimation,
            p.edge_samples
        ),
        format!(
            "samples: {} in the record, {} decimated inside the edges, {} used; {} left out where |qd| <= {:.3e} rad/s (3 sigma of the velocity estimate's noise: the sign of qd is not trusted there, and stiction is not Fc sign(qd))",
            t.samples_total,
            t.candidates,
            t.used,
            t.candidates - t.used,
            p.velocity_threshold_rad_s
        ),
        format!(
            "Coulomb friction Fc = {fc:.4e} +- {sfc:.2e} N m ({:.1} sigma, needs 3); BIC score {:.1} over the viscous model (needs > 0): {}",
            t.coulomb_sigmas,
            t.coulomb_score,
            if t.coulomb_named { "named" } else { "not named" }
        ),
        format!(
            "relative force error ||y - X theta|| / ||y||: rigid body {:.3} %, with viscous friction {:.3} %, with Coulomb and viscous friction {:.3} %; condition number {:.2}; predicted noise {:.3e} N m per sample (force floor {:.3e} (N m)^2/Hz, position floor through M D2 + Fv D1)",
            pct(t.rigid.relative_error),
            pct(t.rigid_viscous.relative_error),
            pct(t.rigid_friction.relative_error),
            t.rigid_friction.condition,
            t.noise_rms_nm,
            c.force_floor_nm2_per_hz
        ),
        "gap (trajectory path): the force residual of the rigid body without friction (before) and with the friction kept (after), 8.69 dB per unit relative error (0.0869 dB per %); systematic = predicted noise removed; no frequency bands".into(),
        "units: the recording's, torque_cmd_nm [N m] and position_rad [rad]: inertia_kgm2 [kg m^2], viscous_nms_per_rad [N m s/rad], coulomb_nm and offset_nm [N m]; for a prismatic axis whose columns hold N and m, read kg, N s/m and N".into(),
    ];
    let prismatic = recs[0]
        .sidecar
        .source
        .as_deref()
        .is_some_and(|s| s.to_ascii_lowercase().contains("prismatic"));
    if prismatic {
        n.push("the recording's source says the axis is prismatic: its torque_cmd_nm holds a force and position_rad a position in the units the source names (N and m for the EMPS presets); the parameters are then M [kg], Fv [N s/m], Fc and offset [N]".into());
    }
    for x in &t.cross_tests {
        n.push(format!(
            "cross-test on recording {}: relative force error {:.3} % ({} samples, the estimation's processing and parameters)",
            x.recording,
            pct(x.relative_error),
            x.samples
        ));
    }
    if opts.band_hz.is_some() {
        n.push("--band is not used by the trajectory path (the cut-off comes from the position's noise floor)".into());
    }
    n
}

/// The diagnosis of trajectory recordings: the first is identified, every further one is
/// a cross-test. `seconds` and the stages are the caller's to fill.
pub fn diagnose(recs: &[Recording], opts: &DiagnoseOptions) -> Result<Diagnosis, DiagnoseError> {
    let first = recs.first().ok_or(DiagnoseError::NoRecordings)?;
    let mut t = super::identify(first).map_err(|e| DiagnoseError::Trajectory(0, e))?;
    for (i, r) in recs.iter().enumerate().skip(1) {
        let x = super::cross_test(&t, r, i).map_err(|e| DiagnoseError::Trajectory(i, e))?;
        t.cross_tests.push(x);
    }
    let nominal = effect_fit(&t, &t.rigid, Effect::None, 0)?;
    let without = effect_fit(&t, &t.rigid_viscous, Effect::None, 1)?;
    let coulomb = effect_fit(&t, &t.rigid_friction, Effect::CoulombFriction, 1)?;
    let mut ranking = vec![
        ranked(&t, &coulomb, &t.rigid_friction, t.coulomb_score),
        ranked(&t, &without, &t.rigid_viscous, 0.0),
    ];
    ranking.sort_by(|a, b| b.score.total_cmp(&a.score));
    let kept = t.kept_fit();
    let (before, before_raw) = gap_db(&t, &t.rigid);
    let (after, after_raw) = gap_db(&t, kept);
    let winner = t.coulomb_named.then(|| coulomb.clone());
    let verdict = if t.coulomb_named {
        Effect::CoulombFriction
    } else if t.within_noise(kept) {
        Effect::None
    } else {
        Effect::Unexplained
    };
    let effects = winner
        .iter()
        .map(|w| Step {
            effect: w.effect,
            fit: w.clone(),
            after_rms_db: after,
            score: t.coulomb_score,
        })
        .collect();
    let gap = Gap {
        before_rms_db: before,
        after_rms_db: after,
        before_raw_rms_db: before_raw,
        after_raw_rms_db: after_raw,
        before_mag_db: f64::NAN,
        after_mag_db: f64::NAN,
        before_phase_deg: f64::NAN,
        after_phase_deg: f64::NAN,
        noise_rms_db: DB_PER_NEPER * (t.used as f64).sqrt() * t.noise_rms_nm / t.force_norm_nm,
        bands: Vec::new(),
    };
    let residual = ResidualKind {
        reduced_chi2: t.reduced_chi2(&t.rigid),
        within_noise: t.within_noise(&t.rigid),
        changed: false,
        nonlinear: t.coulomb_named,
        linear_model_error: false,
        local: None,
        change_local: None,
        levels: Vec::new(),
        changes: Vec::new(),
    };
    let data = Data {
        levels: Vec::new(),
        fs: first.sample_rate_hz,
        kind: FrfKind::DifferencedVelocity,
        band: opts.band_hz,
        substeps: crate::diagnose::substeps_at(opts.substeps, first.sample_rate_hz),
        spring_substeps: crate::diagnose::substeps_at(opts.spring_substeps, first.sample_rate_hz),
        targets: Vec::new(),
        full_targets: Vec::new(),
        noise: NoiseChi2 {
            mean: 1.0,
            threshold: t.within_noise_threshold,
        },
        torque: None,
    };
    let mut notes = notes(&t, recs, opts);
    if t.kept == Kept::Rigid && !t.coulomb_named {
        notes.push("no friction kept: the gap after is the rigid body's".into());
    }
    Ok(Diagnosis {
        verdict,
        effects,
        masses: 1,
        nominal,
        ranking,
        winner,
        gap,
        residual,
        data,
        notes,
        seconds: 0.0,
        stage_cpu_s: Vec::new(),
        trajectory: Some(t),
        time_cap: crate::diagnose::TimeCap::of(&opts.budget, Vec::new()),
        amplitude_mode: None,
    })
}

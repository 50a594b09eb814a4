//! The diagnosis as JSON (the contract: `verdict`, `effects[{effect, after_rms_db, score,
//! params}]`, `gap.{before_rms_db, after_rms_db,
//! bands[{lo_hz, hi_hz, excess_db}]}`, `ranking[{effect, after_rms_db, score}]`; on the
//! trajectory path also `trajectory{...}`, [`trajectory_json`]; always
//! `time_cap{max_seconds, capped, elapsed_s, not_tried}`, [`time_cap_json`]).

use super::trajectory::{idim::LsFit, Kept, TrajectoryFit};
use super::{rank, Diagnosis};
use serde_json::{json, Value};

fn num(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

/// A linear model (the chain and the nominal extensions): the nominal model's, and the one
/// under each named effect (`effects[i].model`: the chain refitted with the effect).
fn lin_json(l: &super::lti::LinExt) -> Value {
    json!({
        "inertia_kgm2": l.chain.inertia_kgm2,
        "stiffness_nm_per_rad": l.chain.stiffness_nm_per_rad,
        "damping_nms_per_rad": l.chain.damping_nms_per_rad,
        "viscous_nms_per_rad": num(l.motor_b),
        "ground_stiffness_nm_per_rad": l.ground_spring.then(|| num(l.ground_k)),
    })
}

/// A parameter: `name`, `value`, `std` (null: not computed) and `identifiable` (false
/// where the uncertainty exceeds the value: a number not to be read as an estimate; null
/// where no uncertainty was computed).
fn param_json(p: &super::effects::Param) -> Value {
    json!({"name": p.name, "value": num(p.value), "std": num(p.std), "identifiable": p.identifiable()})
}

pub fn to_json(d: &Diagnosis) -> Value {
    let mut v = body_json(d);
    v["time_cap"] = time_cap_json(&d.time_cap);
    v
}

/// `time_cap{max_seconds, capped, elapsed_s, not_tried}` (`max_seconds` null: no cap).
pub fn time_cap_json(t: &super::TimeCap) -> Value {
    json!({
        "max_seconds": t.max_seconds.map(num),
        "capped": t.capped,
        "elapsed_s": num(t.elapsed_s),
        "not_tried": t.not_tried,
    })
}

fn body_json(d: &Diagnosis) -> Value {
    let g = &d.gap;
    json!({
        "verdict": d.verdict,
        "effects": d.effects.iter().map(|s| json!({
            "effect": s.effect, "after_rms_db": num(s.after_rms_db), "score": num(s.score),
            "params": s.fit.params.iter().map(param_json).collect::<Vec<_>>(),
            "model": lin_json(&s.fit.lin),
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
            "converged": rank::nominal_chi2(&d.ranking).is_none_or(|n| r.converged(n)),
            "chi2": num(r.chi2), "added_params": r.added_params,
            "params": r.params.iter().map(param_json).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "effect_params": d.winner.as_ref().map(|w| w.params.iter().map(param_json).collect::<Vec<_>>()),
        "residual": {
            "reduced_chi2": num(d.residual.reduced_chi2),
            "within_noise": d.residual.within_noise,
            "changed_between_levels": d.residual.changed,
            "nonlinear_distortion": d.residual.nonlinear,
            "linear_model_error": d.residual.linear_model_error,
            "levels": d.residual.levels.iter().map(|l| json!({
                "level": l.level, "torque_rms_nm": num(l.torque_rms_nm),
                "detection_excess_db": l.detection_excess_db.map(num),
                "detection_lines_hit": l.detection_lines_hit.map(num),
                "distortion_hz": l.distortion_hz.map(|w| [num(w[0]), num(w[1])]),
                "realisation_excess_db": l.realisation_excess_db.map(num),
            })).collect::<Vec<_>>(),
            "level_changes": d.residual.changes.iter().map(|c| json!({
                "a": c.a, "b": c.b, "mean_z2": num(c.mean_z2), "rms_db": num(c.rms_db), "significant": c.significant,
            })).collect::<Vec<_>>(),
            "local_gap": d.residual.local.map(located_json),
            "local_change": d.residual.change_local.map(located_json),
        },
        "nominal": lin_json(&d.nominal.lin),
        "trajectory": d.trajectory.as_ref().map(trajectory_json),
        "amplitude_mode": d.amplitude_mode.as_ref().map(amplitude_mode_json),
        "torque_path": d.data.torque.as_ref().map(torque_path_json),
        "notes": d.notes,
        "seconds": num(d.seconds),
    })
}

fn ls_json(t: &TrajectoryFit, f: &LsFit) -> Value {
    json!({
        "params": f.columns.iter().zip(f.theta.iter().zip(&f.std)).map(|(c, (v, s))| json!({
            "name": c.name(), "value": num(*v), "std": num(*s),
        })).collect::<Vec<_>>(),
        "residual_rss_nm2": num(f.rss),
        "relative_error_pct": num(100.0 * f.relative_error),
        "condition_number": num(f.condition),
        "reduced_chi2": num(t.reduced_chi2(f)),
        "within_noise": t.within_noise(f),
    })
}

/// The trajectory path's figures: the kept model's parameters (`params`, the units in
/// the names: the recording's, N m and rad), each nested model, the cut-off and how it was
/// found, the samples, the noise, the significance tests and the cross-tests.
pub fn trajectory_json(t: &TrajectoryFit) -> Value {
    let kept = t.kept_fit();
    let p = &t.processing;
    let c = &t.cutoff;
    json!({
        "method": "idim_ls",
        "model": match t.kept {
            Kept::Rigid => "rigid",
            Kept::RigidViscous => "rigid_viscous",
            Kept::RigidFriction => "rigid_coulomb_viscous",
        },
        "params": ls_json(t, &t.rigid_friction)["params"].clone(),
        "kept": ls_json(t, kept),
        "models": {
            "rigid": ls_json(t, &t.rigid),
            "rigid_viscous": ls_json(t, &t.rigid_viscous),
            "rigid_coulomb_viscous": ls_json(t, &t.rigid_friction),
        },
        "relative_error_pct": num(100.0 * t.rigid_friction.relative_error),
        "condition_number": num(t.rigid_friction.condition),
        "viscous": {"sigmas": num(t.viscous_sigmas), "bic_score": num(t.viscous_score), "significant": t.viscous_significant},
        "coulomb": {"sigmas": num(t.coulomb_sigmas), "bic_score": num(t.coulomb_score), "named": t.coulomb_named},
        "cutoff_hz": num(c.cutoff_hz),
        "cutoff_capped": c.capped,
        "cutoff_rule": "position spectrum (1/3-octave median) at twice its white-noise floor",
        "floor_band_hz": [num(c.floor_band_hz[0]), num(c.floor_band_hz[1])],
        "welch_resolution_hz": num(c.resolution_hz),
        "position_floor_rad2_per_hz": num(c.position_floor_rad2_per_hz),
        "force_floor_nm2_per_hz": num(c.force_floor_nm2_per_hz),
        "butterworth_order": p.filter.order,
        "decimation": p.decimation,
        "edge_samples": p.edge_samples,
        "pad_samples": p.filter.pad_samples(t.samples_total),
        "velocity_threshold_rad_s": num(p.velocity_threshold_rad_s),
        "spread_samples": p.spread_samples,
        "velocity_noise_rad_s": num(t.velocity_noise_rad_s),
        "noise_rms_nm": num(t.noise_rms_nm),
        "within_noise_threshold": num(t.within_noise_threshold),
        "samples_total": t.samples_total,
        "samples_candidates": t.candidates,
        "samples_used": t.used,
        "cross_tests": t.cross_tests.iter().map(|x| json!({
            "recording": x.recording, "samples": x.samples,
            "relative_error_pct": num(100.0 * x.relative_error),
        })).collect::<Vec<_>>(),
    })
}

/// The most significant run of lines of a localised scan ([`super::scan`]): where, how
/// many lines, the probability of one run under noise alone and the runs tried.
/// The drive's torque reading against its command ([`super::torque_path`]).
fn torque_path_json(t: &super::torque_path::TorquePath) -> Value {
    use super::torque_path::Shape;
    let lines = t.lines().max(1) as f64;
    let fit = |f: &super::torque_path::PathFit| {
        json!({
            "loop_order": f.lp.map(|l| l.order),
            "loop_bandwidth_hz": f.lp.map(|l| num(l.bandwidth_hz)),
            "loop_damping_ratio": f.lp.filter(|l| l.order == 2).map(|l| num(l.zeta)),
            "command_delay_samples": num(f.delay_s * t.fs),
            "gain": num(f.gain),
            "reduced_chi2": num(f.chi2 / lines),
        })
    };
    json!({
        "shape": match t.shape {
            Shape::Clean => "clean",
            Shape::Loop => "current_loop",
            Shape::Departs => "departs",
        },
        "lines": t.lines(),
        "noise_threshold_reduced_chi2": num(t.noise.threshold),
        "clean": fit(&t.clean),
        "with_loop": fit(&t.with_loop),
    })
}

/// The modes of the band where the FRF changes between levels, per level, and the
/// change named ([`super::amplitude_mode`]); `null` standard deviations or shifts where a
/// figure is not identifiable.
pub fn amplitude_mode_json(a: &super::amplitude_mode::AmplitudeMode) -> Value {
    let named = a.named.map(|nm| {
        let t = &a.modes[nm.mode];
        json!({
            "change": nm.change.name(),
            "mode": nm.mode,
            "frequency_hz": t.at[a.low].map(|m| num(m.f_hz)),
            "frequency_shift_sigmas": t.f_shift_sigmas.map(num),
            "damping_shift_sigmas": t.zeta_shift_sigmas.map(num),
        })
    });
    json!({
        "change_band_hz": [num(a.change_hz[0]), num(a.change_hz[1])],
        "fit_band_hz": [num(a.band_hz[0]), num(a.band_hz[1])],
        "compared_levels": [a.levels[a.low].level, a.levels[a.high].level],
        "tests": a.tests,
        "z_crit": num(a.z_crit),
        "dof": a.dof,
        "named": named,
        "levels": a.levels.iter().map(|l| json!({
            "level": l.level,
            "torque_rms_nm": num(l.torque_rms),
            "lines": l.fit.as_ref().map(|f| f.lines),
            "reduced_chi2": l.fit.as_ref().map(|f| num(f.reduced_chi2())),
            "covariance_scale": l.fit.as_ref().map(|f| num(f.scale)),
        })).collect::<Vec<_>>(),
        "modes": a.modes.iter().map(|t| json!({
            "frequency_shift_sigmas": t.f_shift_sigmas.map(num),
            "damping_shift_sigmas": t.zeta_shift_sigmas.map(num),
            "change_z2": t.change_z2.map(num),
            "change_rms_db": t.change_db.map(num),
            "levels": a.levels.iter().zip(t.at.iter().zip(&t.identified)).map(|(l, (m, ok))| json!({
                "level": l.level,
                "identified": ok,
                "frequency_hz": m.map(|m| num(m.f_hz)),
                "frequency_std_hz": m.map(|m| num(m.f_std_hz)),
                "damping_ratio": m.map(|m| num(m.zeta)),
                "damping_ratio_std": m.map(|m| num(m.zeta_std)),
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
    })
}

fn located_json(w: super::Located) -> Value {
    json!({
        "level": w.pair.is_none().then_some(w.window.series),
        "levels": w.pair.map(|(a, b)| [a, b]),
        "lo_hz": num(w.window.lo_hz), "hi_hz": num(w.window.hi_hz), "lines": w.window.lines,
        "p_noise_per_run": num(w.window.p), "runs_tried": w.window.tests,
        "significant": w.window.significant,
    })
}

#[cfg(test)]
mod tests {
    use super::param_json;
    use crate::diagnose::effects::Param;

    #[test]
    fn a_parameter_the_data_do_not_fix_is_marked_so() {
        let p = |value: f64, std: f64| Param {
            name: "delay_s".into(),
            value,
            std,
        };
        assert_eq!(param_json(&p(0.0, 50.0))["identifiable"], false);
        // bounded on one side only: not identifiable, and no infinite number written
        let one_sided = param_json(&p(1.9e84, f64::INFINITY));
        assert_eq!(one_sided["identifiable"], false);
        assert!(one_sided["std"].is_null());
        assert_eq!(param_json(&p(1e-3, 1e-5))["identifiable"], true);
        let none = param_json(&p(1e-3, f64::NAN));
        assert!(none["identifiable"].is_null() && none["std"].is_null());
    }
}

//! The readable report of a diagnosis that took the trajectory path (IDIM-LS of the rigid
//! body with friction).

use flexid_core::diagnose::trajectory::{idim::LsFit, TrajectoryFit};
use flexid_core::diagnose::Diagnosis;
use std::fmt::Write;

fn params(s: &mut String, f: &LsFit) {
    for (c, (v, sd)) in f.columns.iter().zip(f.theta.iter().zip(&f.std)) {
        let _ = writeln!(s, "    {:22} {v:14.6e} +- {sd:.2e}", c.name());
    }
}

/// The report: verdict, parameters with their standard deviations, the models' relative
/// force errors, the gap, the cut-off and samples, cross-tests, notes.
pub fn render_trajectory(d: &Diagnosis, t: &TrajectoryFit) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "flexid diagnose: trajectory path (not periodic, one body): IDIM-LS of tau = M qdd + Fv qd + Fc sign(qd) + offset"
    );
    let _ = writeln!(s, "\nVERDICT: {}", d.verdict);
    let _ = writeln!(
        s,
        "\nRigid body with Coulomb and viscous friction (units of the recording: N m, rad; a prismatic axis reads N, m):"
    );
    params(&mut s, &t.rigid_friction);
    let _ = writeln!(
        s,
        "  condition number {:.2}; Coulomb {:.1} sigma, BIC score {:.1}; viscous {:.1} sigma, BIC score {:.1}",
        t.rigid_friction.condition, t.coulomb_sigmas, t.coulomb_score, t.viscous_sigmas, t.viscous_score
    );
    let _ = writeln!(s, "\nRelative force error ||y - X theta|| / ||y||:");
    for (name, f) in [
        ("rigid body, no friction", &t.rigid),
        ("with viscous friction", &t.rigid_viscous),
        ("with Coulomb and viscous friction", &t.rigid_friction),
    ] {
        let _ = writeln!(
            s,
            "  {name:36} {:8.3} %   (RSS / N) / noise^2 = {:.3e}{}",
            100.0 * f.relative_error,
            t.reduced_chi2(f),
            if t.within_noise(f) {
                " (within noise)"
            } else {
                ""
            }
        );
    }
    for x in &t.cross_tests {
        let _ = writeln!(
            s,
            "  cross-test, recording {}: {:.3} % ({} samples)",
            x.recording,
            100.0 * x.relative_error,
            x.samples
        );
    }
    let g = &d.gap;
    let _ = writeln!(
        s,
        "\ngap (force residual, 8.69 dB per unit relative error, noise removed): rigid body {:.3} dB -> model kept {:.3} dB; with noise {:.3} -> {:.3} dB; noise alone {:.3} dB",
        g.before_rms_db, g.after_rms_db, g.before_raw_rms_db, g.after_raw_rms_db, g.noise_rms_db
    );
    let p = &t.processing;
    let _ = writeln!(
        s,
        "cut-off {:.2} Hz (position spectrum at twice its noise floor{}), decimation {}, samples used {} of {}",
        t.cutoff.cutoff_hz,
        if t.cutoff.capped { ", capped" } else { "" },
        p.decimation,
        t.used,
        t.candidates
    );
    for n in &d.notes {
        let _ = writeln!(s, "note: {n}");
    }
    let _ = writeln!(s, "({:.2} s)", d.seconds);
    s
}

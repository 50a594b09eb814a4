//! The readable report of a diagnosis.

use flexid_core::diagnose::Diagnosis;
use std::fmt::Write;

pub fn render(d: &Diagnosis) -> String {
    if let Some(t) = &d.trajectory {
        return super::trajectory::render_trajectory(d, t);
    }
    let mut s = String::new();
    let g = &d.gap;
    let _ = writeln!(
        s,
        "flexid diagnose: nominal {}-mass chain, {} recording(s), {} lines",
        d.masses,
        d.data.levels.len(),
        d.data.lines()
    );
    let _ = writeln!(s, "\nVERDICT: {}", d.verdict);
    if d.time_cap.capped {
        let _ = writeln!(s, "{} (--max-seconds)", d.time_cap.words());
    }
    if d.effects.len() > 1 {
        let _ = writeln!(s, "effects (forward selection, strongest first):");
        for st in &d.effects {
            let _ = writeln!(
                s,
                "  + {:20} gap after {:.3} dB (score {:.1})",
                st.effect, st.after_rms_db, st.score
            );
        }
    }
    if let Some(a) = &d.amplitude_mode {
        amplitude_mode(&mut s, a);
    }
    if d.verdict == flexid_core::diagnose::Effect::Unexplained {
        let _ = writeln!(
            s,
            "  the gap is larger than the noise, but no candidate explains it: the cause may be outside the library. Evidence:"
        );
        for (b, _) in &d.gap.bands {
            let _ = writeln!(
                s,
                "  - level {}: {} around {:.2} Hz (core {:.2} - {:.2} Hz), {:.2} dB / {:.1} deg",
                b.level,
                b.shape.words(),
                b.peak_hz,
                b.core_lo_hz,
                b.core_hi_hz,
                b.excess_db,
                b.excess_deg
            );
        }
        for l in &d.residual.levels {
            if let (Some(e), Some(w)) = (l.detection_excess_db, l.distortion_hz) {
                if e > 6.0 {
                    let _ = writeln!(
                        s,
                        "  - level {}: nonlinear distortion at the non-excited lines, {e:+.1} dB over noise, strongest between {:.2} and {:.2} Hz",
                        l.level, w[0], w[1]
                    );
                }
            }
        }
    }
    let _ = writeln!(
        s,
        "gap (systematic RMS log-complex, noise removed, 1 rad of phase = 8.69 dB): before {:.3} dB, after {:.3} dB ({})\n  plain RMS incl. noise {:.3} -> {:.3} dB; noise alone {:.3} dB",
        g.before_rms_db,
        g.after_rms_db,
        shrink_words(g.before_rms_db, g.after_rms_db),
        g.before_raw_rms_db,
        g.after_raw_rms_db,
        g.noise_rms_db
    );
    let _ = writeln!(
        s,
        "  magnitude {:.3} -> {:.3} dB, phase {:.2} -> {:.2} deg",
        g.before_mag_db, g.after_mag_db, g.before_phase_deg, g.after_phase_deg
    );
    let r = &d.residual;
    let _ = writeln!(
        s,
        "\nResidual of the nominal model: reduced chi2 {:.2} ({})",
        r.reduced_chi2,
        if r.within_noise {
            "within noise"
        } else {
            "significant"
        }
    );
    for l in &r.levels {
        let _ = writeln!(
            s,
            "  level {}: torque {:.4} N m RMS; detection lines {}",
            l.level,
            l.torque_rms_nm,
            match (l.detection_excess_db, l.detection_lines_hit) {
                (Some(e), Some(h)) =>
                    format!("{e:+.1} dB over noise, {:.0} % of them > 10 dB", 100.0 * h),
                _ => "none (no odd random-phase design)".into(),
            }
        );
        if let Some(e) = l.realisation_excess_db {
            let _ = writeln!(
                s,
                "    spread over the realisations {e:+.1} dB over the noise alone (median over the lines: stochastic nonlinear distortion when well above 0 dB)"
            );
        }
    }
    for c in &r.changes {
        let _ = writeln!(
            s,
            "  FRF change level {} -> {}: mean z2 {:.2}, RMS {:.3} dB: {}",
            c.a,
            c.b,
            c.mean_z2,
            c.rms_db,
            if c.significant {
                "amplitude dependent"
            } else {
                "within noise"
            }
        );
    }
    for (what, w) in [
        ("nominal model's gap", r.local),
        ("FRF change between levels", r.change_local),
    ] {
        if let Some(w) = w {
            let levels = match w.pair {
                Some((a, b)) => format!("levels {a} -> {b}"),
                None => format!("level {}", w.window.series),
            };
            let _ = writeln!(
                s,
                "  {what}, most significant run of lines: {levels}, {:.3} - {:.3} Hz ({} lines), noise alone {:.1e} per run x {} runs tried: {}",
                w.window.lo_hz,
                w.window.hi_hz,
                w.window.lines,
                w.window.p,
                w.window.tests,
                if w.window.significant {
                    "significant"
                } else {
                    "within noise"
                }
            );
        }
    }
    let _ = writeln!(
        s,
        "  => noise {}, nonlinear distortion {}, linear model error {}",
        if r.gap_is_real() { "not alone" } else { "only" },
        if r.nonlinear { "present" } else { "not seen" },
        if r.linear_model_error {
            "present"
        } else {
            "not seen"
        }
    );
    let _ = writeln!(
        s,
        "\nBands where the difference is significant (nominal model):"
    );
    if g.bands.is_empty() {
        let _ = writeln!(s, "  none");
    }
    for (b, after) in &g.bands {
        let _ = writeln!(
            s,
            "  level {} {:9.3} - {:9.3} Hz ({:4} lines; core {:.3} - {:.3} Hz, {}): {:.2} dB, {:.1} deg [{}{}], mean z2 {:.1}; after {:.2} dB",
            b.level,
            b.lo_hz,
            b.hi_hz,
            b.lines,
            b.core_lo_hz,
            b.core_hi_hz,
            b.shape.words(),
            b.excess_db,
            b.excess_deg,
            if b.magnitude_significant { "mag " } else { "" },
            if b.phase_significant { "phase" } else { "" },
            b.mean_z2,
            after
        );
    }
    let _ = writeln!(
        s,
        "\nRanking (score = chi2 reduction - added params x ln(lines)):"
    );
    let nominal_chi2 = flexid_core::diagnose::rank::nominal_chi2(&d.ranking);
    for k in &d.ranking {
        if nominal_chi2.is_some_and(|n| !k.converged(n)) {
            let _ = writeln!(
                s,
                "  {:20} fit did not converge (ended above the nominal model's chi2): not judged",
                k.effect
            );
            continue;
        }
        let ps: Vec<String> = k.params.iter().map(param_text).collect();
        let _ = writeln!(
            s,
            "  {:20} after {:8.3} dB  score {:12.1}  {}",
            k.effect,
            k.after_rms_db,
            k.score,
            ps.join(", ")
        );
    }
    for n in &d.notes {
        let _ = writeln!(s, "note: {n}");
    }
    let _ = writeln!(s, "({:.2} s)", d.seconds);
    s
}

/// A candidate's parameter: `value +- std`; an uncertainty that was not computed is said
/// so, never printed as NaN; one larger than the value says the data do not fix the
/// parameter (a current loop's bandwidth of 6e12 Hz +- 3e21, a delay of 0 +- 50 s: the
/// fit ran to where the cost no longer changes), so no number is printed as if it were an
/// estimate.
fn param_text(p: &flexid_core::diagnose::effects::Param) -> String {
    match p.identifiable() {
        None => format!("{} = {:.4e} (uncertainty not computed)", p.name, p.value),
        Some(true) if p.std == 0.0 => format!("{} = {:.4e}", p.name, p.value),
        Some(true) => format!("{} = {:.4e} +- {:.1e}", p.name, p.value, p.std),
        Some(false) => format!(
            "{}: {} (uncertainty larger than the value)",
            p.name,
            super::analysis::NOT_IDENTIFIABLE
        ),
    }
}

/// The modes of the band where the FRF changes between levels, per level, and what
/// changes ([`flexid_core::diagnose::amplitude_mode`]).
fn amplitude_mode(s: &mut String, a: &flexid_core::diagnose::amplitude_mode::AmplitudeMode) {
    let _ = writeln!(
        s,
        "  modes of {:.2} - {:.2} Hz (the FRF changes between levels in {:.2} - {:.2} Hz), fitted at each level; levels {} and {} compared, |z| > {:.2} significant ({} comparisons):",
        a.band_hz[0],
        a.band_hz[1],
        a.change_hz[0],
        a.change_hz[1],
        a.levels[a.low].level,
        a.levels[a.high].level,
        a.z_crit,
        a.tests
    );
    match a.named {
        Some(nm) => {
            let _ = writeln!(s, "  => {} of mode {}", nm.change.name(), nm.mode + 1);
        }
        None => {
            let _ = writeln!(s, "  => no mode changes significantly");
        }
    }
    let sig =
        |z: Option<f64>| z.map_or("not identifiable".to_string(), |z| format!("{z:+.1} sigma"));
    for (i, t) in a.modes.iter().enumerate() {
        let _ = writeln!(
            s,
            "  mode {}: frequency shift {}, damping shift {}; the FRF change it makes alone: {}",
            i + 1,
            sig(t.f_shift_sigmas),
            sig(t.zeta_shift_sigmas),
            match (t.change_z2, t.change_db) {
                (Some(c), Some(db)) => format!("z2 {c:.4e}, RMS {db:.3} dB"),
                _ => "not identifiable".to_string(),
            }
        );
        for (l, (m, ok)) in a.levels.iter().zip(t.at.iter().zip(&t.identified)) {
            match m {
                Some(m) => {
                    let _ = writeln!(
                        s,
                        "    level {} ({:.4} RMS): {:.4} +- {:.4} Hz, damping ratio {:.4} +- {:.4}{}",
                        l.level,
                        l.torque_rms,
                        m.f_hz,
                        m.f_std_hz,
                        m.zeta,
                        m.zeta_std,
                        if *ok {
                            ""
                        } else {
                            " (not identified: at a bound or not determined within it at 3 sigma)"
                        }
                    );
                }
                None => {
                    let _ = writeln!(s, "    level {}: not identifiable", l.level);
                }
            }
        }
    }
}

/// How far the gap shrank, as a factor; where nothing is left beyond the noise at the
/// printed precision (0.000 dB), that, not a factor of 1e11.
fn shrink_words(before_db: f64, after_db: f64) -> String {
    if after_db < 5e-4 {
        "nothing left beyond the noise".into()
    } else {
        format!("{:.1}x", before_db / after_db)
    }
}

#[cfg(test)]
mod shrink_tests {
    use super::shrink_words;

    #[test]
    fn a_gap_removed_to_the_noise_is_said_so_not_as_a_huge_factor() {
        assert_eq!(shrink_words(0.698, 1e-12), "nothing left beyond the noise");
        assert_eq!(shrink_words(0.698, 0.0), "nothing left beyond the noise");
        assert_eq!(shrink_words(0.70, 0.35), "2.0x");
    }
}

#[cfg(test)]
mod param_tests {
    use super::param_text;
    use flexid_core::diagnose::effects::Param;

    fn p(value: f64, std: f64) -> Param {
        Param {
            name: "bandwidth_3db_hz".into(),
            value,
            std,
        }
    }

    #[test]
    fn a_parameter_the_data_do_not_fix_prints_no_number() {
        // where the fit ran off to (a loop at 6e12 Hz +- 3e21): said, not printed
        let t = param_text(&p(5.6591e12, 3.2e21));
        assert!(t.contains("not identifiable"), "{t}");
        assert!(!t.contains("e12") && !t.contains("e21"), "{t}");
        // a delay of zero +- 50 s alike
        assert!(param_text(&p(0.0, 50.0)).contains("not identifiable"));
        // a spring that does not act (x_ref of 1.9e84 rad, bounded on one side only)
        let t = param_text(&p(1.9e84, f64::INFINITY));
        assert!(t.contains("not identifiable") && !t.contains("e84"), "{t}");
        // an estimate keeps its number and uncertainty; none computed is said so
        assert_eq!(
            param_text(&p(412.0, 3.5)),
            "bandwidth_3db_hz = 4.1200e2 +- 3.5e0"
        );
        assert!(param_text(&p(412.0, f64::NAN)).contains("uncertainty not computed"));
        assert_eq!(param_text(&p(1.0, 0.0)), "bandwidth_3db_hz = 1.0000e0");
    }
}

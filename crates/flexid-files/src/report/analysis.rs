use flexid_core::analysis::Analysis;
use std::fmt::Write;

/// One sigma relative to the value, or "not identifiable" where the data do not fix the
/// parameter: its standard deviation is undefined or larger than the value itself (a
/// relative uncertainty above 100 % says nothing but that).
fn pct(std: f64, v: f64) -> String {
    if std.is_finite() && v != 0.0 && std <= v.abs() {
        format!("{:.2} %", 100.0 * std / v.abs())
    } else {
        NOT_IDENTIFIABLE.into()
    }
}

/// How the report prints a parameter the data do not fix.
pub const NOT_IDENTIFIABLE: &str = "not identifiable";

/// The analysis as a readable report (units in every heading, uncertainties as one sigma):
/// the measured FRF, step 1 (total inertia), the anti-resonance/resonance pairs, the
/// paper's step-by-step and exact inverses, the identified model with where its
/// compliance is, and the notes.
pub fn render_report(a: &Analysis, title: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "flexid identify: {title}");
    if let Some(m) = a.time_cap.as_ref().and_then(|t| t.message()) {
        let _ = writeln!(s, "{m}");
    }
    measured_section(&mut s, a);
    total_inertia_section(&mut s, a);
    pairs_section(&mut s, a);
    inverse_section(&mut s, a);
    model_section(&mut s, a);
    notes_section(&mut s, a);
    s
}

/// The measured FRF: estimator, averages, lines, the median line uncertainty.
fn measured_section(s: &mut String, a: &Analysis) {
    let m = &a.measured;
    let f = &m.frf;
    let rel: Vec<f64> = (0..f.len())
        .map(|i| f.relative_std(i))
        .filter(|v| v.is_finite())
        .collect();
    let mut sorted = rel.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN);
    // a relative uncertainty above 100 % is no number to read: say what it means
    let uncertainty = if median.is_finite() && median <= 1.0 {
        format!(
            "{:.2} % ({:.3} dB)",
            100.0 * median,
            20.0 * (1.0 + median).log10()
        )
    } else {
        "larger than the response (the typical line carries no information)".into()
    };
    let _ = writeln!(
        s,
        "FRF: {} estimator, {} {} averaged, {} lines {:.3} .. {:.3} Hz, fs {} Hz, {:?} response; median line uncertainty {uncertainty}",
        m.method,
        m.averages,
        if m.method == "welch_h1" { "segments" } else { "periods" },
        f.len(),
        f.freq_hz.first().copied().unwrap_or(0.0),
        f.freq_hz.last().copied().unwrap_or(0.0),
        a.sample_rate_hz,
        f.kind,
    );
    if a.delay_samples > 0 {
        let _ = writeln!(
            s,
            "command delay: {} samples (from the recording)",
            a.delay_samples
        );
    }
}

/// Step 1: the total inertia and where it came from.
fn total_inertia_section(s: &mut String, a: &Analysis) {
    let _ = writeln!(s);
    match &a.total_inertia {
        Some(t) => {
            let _ = writeln!(
                s,
                "Step 1  total inertia J = {:.5e} kg m^2 +- {} ({})",
                t.j_kgm2,
                pct(t.std_kgm2, t.j_kgm2),
                t.source.replace('_', " ")
            );
            if let Some(e) = &t.estimate {
                let _ = writeln!(
                    s,
                    "        from {} lines {:.3} .. {:.3} Hz, chi2/dof {:.2}{}",
                    e.lines_used,
                    e.band_hz[0],
                    e.band_hz[1],
                    e.chi2_per_dof,
                    if e.curvature_corrected {
                        ", curvature extrapolated to 0 Hz"
                    } else {
                        ""
                    }
                );
            }
        }
        None => {
            let _ = writeln!(s, "Step 1  total inertia: not determined");
        }
    }
}

/// The detected anti-resonance/resonance pairs, the most significant rejected candidates
/// and the significant resonance peaks.
fn pairs_section(s: &mut String, a: &Analysis) {
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "Anti-resonance / resonance pairs (a +180 deg phase rise marks a compliant coupling)"
    );
    if a.detection.pairs.is_empty() {
        let _ = writeln!(
            s,
            "  none detected: the axis behaves as one rigid inertia in this band"
        );
    } else {
        let _ = writeln!(
            s,
            "  (located on the measurement; +- from a local fit around each pair, line scatter only: the identified model's frequencies below carry the uncertainty to quote)"
        );
        let _ = writeln!(
            s,
            "  {:>4}  {:>20}  {:>20}  {:>11}  {:>7}  {:>10}",
            "pair", "AR [Hz]", "R [Hz]", "(fR/fAR)^2", "L [dB]", "rise [deg]"
        );
        for (k, p) in a.detection.pairs.iter().enumerate() {
            let m = (p.r_hz / p.ar_hz).powi(2);
            let _ = writeln!(
                s,
                "  {:>4}  {:>20}  {:>20}  {:>11.4}  {:>7.2}  {:>10.0}",
                k + 1,
                freq(p.ar_hz, p.ar_std_hz, p.ar_below_band, "<"),
                freq(p.r_hz, p.r_std_hz, p.r_above_band, ">"),
                m,
                20.0 * m.log10(),
                p.phase_rise_deg
            );
        }
    }
    for p in &a.detection.unconfirmed {
        let _ = writeln!(
            s,
            "  unconfirmed {} / {} Hz ({:.0} sigma, phase rise only {:.0} deg): offered to the order selection, kept only if the data need it",
            freq(p.ar_hz, p.ar_std_hz, p.ar_below_band, "<").trim(),
            freq(p.r_hz, p.r_std_hz, p.r_above_band, ">").trim(),
            p.prominence_sigma,
            p.phase_rise_deg
        );
    }
    let mut rejected: Vec<_> = a.detection.rejected.iter().collect();
    rejected.sort_by(|x, y| y.prominence_sigma.total_cmp(&x.prominence_sigma));
    const SHOWN: usize = 6;
    if rejected.len() > SHOWN {
        let _ = writeln!(
            s,
            "  ({} candidates rejected; the {SHOWN} most significant:)",
            rejected.len()
        );
    }
    for r in rejected.iter().take(SHOWN) {
        let _ = writeln!(
            s,
            "  rejected {:?} at {:.3} Hz ({:.1} dB, {:.1} sigma): {}",
            r.kind, r.freq_hz, r.prominence_db, r.prominence_sigma, r.reason
        );
    }
    if !a.detection.peaks.is_empty() {
        let _ = writeln!(
            s,
            "  significant resonance peaks (paired or not; * = resonance of a pair above):"
        );
        for p in &a.detection.peaks {
            let _ = writeln!(
                s,
                "    {:>20} {} ({:.1} dB, {:.0} sigma)",
                freq(p.freq_hz, p.std_hz, false, ""),
                if p.paired { "*" } else { " " },
                p.prominence_db,
                p.prominence_sigma
            );
        }
    }
}

/// The paper's step-by-step inverse and the exact (Cauer) inverse.
fn inverse_section(s: &mut String, a: &Analysis) {
    if let Some(p) = &a.paper {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Paper step-by-step (each pair an isolated two-body reducer, lowest first)"
        );
        for st in &p.pairs {
            let _ = writeln!(
                s,
                "  pair {}: {} = {:.5e} kg m^2, J{} = {:.5e} kg m^2 switched off, c{} = {:.5e} N m/rad",
                st.pair,
                if st.body == 2 { "J1".to_string() } else { format!("J1+..+J{}", st.body - 1) },
                st.inertia_above_kgm2,
                st.body,
                st.body_inertia_kgm2,
                st.coupling,
                st.stiffness_nm_per_rad
            );
        }
    }
    if let Some(e) = &a.exact {
        let _ = writeln!(s, "Exact inverse (the chain with exactly these spectra):");
        let _ = writeln!(s, "  J [kg m^2] = {}", list(&e.inertia_kgm2));
        let _ = writeln!(s, "  c [N m/rad] = {}", list(&e.stiffness_nm_per_rad));
    }
}

/// What the reduced chi-square says about the model and the uncertainties. With `dof =
/// 2 lines - params` degrees of freedom and residuals at the noise level, `chi2/dof` is
/// 1 +- sqrt(2/dof); above 1 + 3 sqrt(2/dof) the model leaves structure the noise does
/// not explain, and the fit's covariance has been scaled by `chi2/dof` (the standard
/// deviations by its square root).
pub(crate) fn chi2_statement(chi2_per_dof: f64, lines: usize, params: usize) -> String {
    let dof = (2 * lines).saturating_sub(params).max(1) as f64;
    let spread = (2.0 / dof).sqrt();
    if !chi2_per_dof.is_finite() {
        "reduced chi-square undefined (no degrees of freedom): uncertainties from the line variances alone".into()
    } else if chi2_per_dof > 1.0 + 3.0 * spread {
        format!(
            "residual above the measurement noise (chi2/dof {chi2_per_dof:.2}, noise alone gives 1 +- {spread:.3}): the model misses part of the response; uncertainties scaled by sqrt(chi2/dof) = {:.2}",
            chi2_per_dof.sqrt()
        )
    } else {
        format!(
            "residual at the measurement noise (chi2/dof {chi2_per_dof:.2}, noise alone gives 1 +- {spread:.3}): uncertainties from the line variances{}",
            if chi2_per_dof > 1.0 {
                format!(", scaled by sqrt(chi2/dof) = {:.2}", chi2_per_dof.sqrt())
            } else {
                String::new()
            }
        )
    }
}

/// The identified model: inertias, stiffnesses and dampings with one sigma, its modes,
/// where the compliance is, and the model orders tried.
fn model_section(s: &mut String, a: &Analysis) {
    if let (Some(fit), Some(model)) = (&a.fit, &a.model) {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Identified model: {} bodies (Levenberg-Marquardt, {} starts, {} reached the best; chi2/dof {:.2}; residual {:.3} dB / {:.2} deg RMS over {} lines)",
            model.masses,
            fit.starts,
            fit.starts_converged,
            fit.chi2_per_dof,
            fit.residual_rms_db,
            fit.residual_rms_deg,
            fit.lines_used
        );
        let _ = writeln!(
            s,
            "  {}",
            chi2_statement(fit.chi2_per_dof, fit.lines_used, fit.params)
        );
        let _ = writeln!(
            s,
            "  {:<6} {:>14} {:>16}",
            "body", "J [kg m^2]", "+- 1 sigma"
        );
        for i in 0..model.masses {
            let _ = writeln!(
                s,
                "  J{:<5} {:>14.5e} {:>16}{}",
                i + 1,
                model.inertia_kgm2[i],
                pct(model.inertia_std_kgm2[i], model.inertia_kgm2[i]),
                if i == 0 { "  (motor side)" } else { "" }
            );
        }
        if let Some(g) = &model.ground_damping {
            let _ = writeln!(
                s,
                "  b motor-ground   {:>14.4e} {:>16}  viscous friction [N m s/rad], from the lowest lines",
                g.b_nms_per_rad,
                pct(g.std_nms_per_rad, g.b_nms_per_rad)
            );
        }
        if model.masses > 1 {
            let _ = writeln!(
                s,
                "  {:<10} {:>14} {:>16} {:>16} {:>16}",
                "coupling", "c [N m/rad]", "+- 1 sigma", "d [N m s/rad]", "+- 1 sigma"
            );
            for i in 0..model.masses - 1 {
                let _ = writeln!(
                    s,
                    "  c{:<2}J{}-J{:<3} {:>14.5e} {:>16} {:>16.4e} {:>16}",
                    i + 1,
                    i + 1,
                    i + 2,
                    model.stiffness_nm_per_rad[i],
                    pct(
                        model.stiffness_std_nm_per_rad[i],
                        model.stiffness_nm_per_rad[i]
                    ),
                    model.damping_nms_per_rad[i],
                    pct(
                        model.damping_std_nms_per_rad[i],
                        model.damping_nms_per_rad[i]
                    )
                );
            }
            let _ = writeln!(
                s,
                "  model AR [Hz] = {}",
                list_std(&model.antiresonance_hz, &model.antiresonance_std_hz)
            );
            let _ = writeln!(
                s,
                "  model R  [Hz] = {}",
                list_std(&model.resonance_hz, &model.resonance_std_hz)
            );
            let _ = writeln!(s, "  damping ratio = {}", list(&model.damping_ratio));
            let _ = writeln!(s);
            let _ = writeln!(s, "Where the compliance is:");
            for c in &model.couplings {
                let _ = writeln!(
                    s,
                    "  resonance {:.3} Hz: coupling c{} between body {} and body {} (c = {:.4e} N m/rad) holds {:.0} % of the mode's strain energy",
                    c.resonance_hz,
                    c.index,
                    c.index,
                    c.index + 1,
                    c.stiffness_nm_per_rad,
                    100.0 * c.strain_energy_share
                );
            }
            if let Some(lowest) = model.couplings.first() {
                let _ = writeln!(
                    s,
                    "  -> the lowest resonance limits the servo bandwidth: stiffening coupling c{} raises it",
                    lowest.index
                );
            }
        }
        if !a.orders.is_empty() {
            let chosen = model.masses;
            let items: Vec<String> = a
                .orders
                .iter()
                .map(|o| match &o.error {
                    Some(e) if e.contains(flexid_core::identify::fit::NOT_TRIED) => {
                        format!("{} bodies not tried (time cap)", o.masses)
                    }
                    Some(e) if o.cost.is_finite() => {
                        format!("{} bodies BIC {:.1} refused ({e})", o.masses, o.bic)
                    }
                    Some(e) => format!("{} bodies failed ({e})", o.masses),
                    None => format!(
                        "{} bodies BIC {:.1}{}",
                        o.masses,
                        o.bic,
                        if o.masses == chosen { " (chosen)" } else { "" }
                    ),
                })
                .collect();
            let _ = writeln!(s, "Model order: {}", items.join(", "));
        }
    }
}

/// The notes of the analysis.
fn notes_section(s: &mut String, a: &Analysis) {
    if !a.notes.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(s, "Notes:");
        for n in &a.notes {
            let _ = writeln!(s, "  - {n}");
        }
    }
}

/// `x +- s` with at least 3 decimals and as many more (up to 8) as the uncertainty's two
/// leading digits need: never "+- 0.000" for an uncertainty that is not zero.
fn pm(x: f64, s: f64) -> String {
    let d = if s > 0.0 {
        ((-s.log10()).ceil() as i64 + 1).clamp(3, 8) as usize
    } else {
        3
    };
    if s > 0.0 && s < 0.5 * 10f64.powi(-(d as i32)) {
        // below what 8 decimals show: the uncertainty in exponent form
        return format!("{x:.d$} +- {s:.1e}");
    }
    format!("{x:.d$} +- {s:.d$}")
}

fn freq(v: f64, std: f64, bound: bool, sign: &str) -> String {
    if bound {
        format!("{sign} {v:.3} (edge)")
    } else if std.is_finite() {
        pm(v, std)
    } else {
        format!("{v:.3}")
    }
}

/// Frequencies with their one-sigma uncertainties (from the fit's covariance): `f +- s`,
/// or the value alone where the uncertainty is undefined or larger than the value.
fn list_std(v: &[f64], std: &[f64]) -> String {
    let items: Vec<String> = v
        .iter()
        .zip(std.iter().chain(std::iter::repeat(&f64::NAN)))
        .map(|(x, s)| {
            if !x.is_finite() {
                "n/a".into()
            } else if s.is_finite() && *s <= x.abs() {
                pm(*x, *s)
            } else {
                format!("{x:.3} ({NOT_IDENTIFIABLE})")
            }
        })
        .collect();
    format!("[{}]", items.join(", "))
}

fn list(v: &[f64]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|x| {
            if x.is_finite() {
                format!("{x:.5e}")
            } else {
                "n/a".into()
            }
        })
        .collect();
    format!("[{}]", items.join(", "))
}

#[cfg(test)]
mod tests {
    use super::chi2_statement;

    #[test]
    fn uncertainties_keep_two_significant_digits() {
        assert_eq!(super::pm(2.899123, 2.04e-5), "2.899123 +- 0.000020");
        assert_eq!(super::pm(380.0829, 0.037), "380.083 +- 0.037");
        assert_eq!(super::pm(5.0, 0.0), "5.000 +- 0.000");
        assert_eq!(super::pm(5.0, 3e-12), "5.00000000 +- 3.0e-12");
    }

    #[test]
    fn the_report_says_when_the_uncertainties_are_scaled_by_model_error() {
        // 1000 lines, 7 parameters: noise alone gives 1 +- 0.032
        let at_noise = chi2_statement(1.03, 1000, 7);
        assert!(at_noise.contains("at the measurement noise"), "{at_noise}");
        let model_error = chi2_statement(1.5, 1000, 7);
        assert!(
            model_error.contains("misses part of the response") && model_error.contains("1.22"),
            "{model_error}"
        );
        assert!(chi2_statement(f64::NAN, 2, 4).contains("undefined"));
    }
}

//! The groups' rules, and the tables the benchmark prints: per group the share right
//! against the target, the confusion matrix (true class x verdict, with `none`,
//! `unexplained` and `error` columns), the gap ratio of every named single effect, the
//! one-core time per diagnosis, and the right answers per measurement axis.

use super::cases::{Group, Truth, GROUPS};
use flexid::diagnose::{Diagnosis, EFFECTS};
use std::fmt::Write;

/// What the diagnosis answered on one case, and whether it was right.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub truth: Truth,
    /// The verdict, or `error`.
    pub verdict: String,
    /// The effects named (`Diagnosis::effects`).
    pub effects: Vec<String>,
    pub before_db: f64,
    pub after_db: f64,
    /// The cores of the localised bands `[core_lo, core_hi]` [Hz] (`gap.bands`).
    pub bands_hz: Vec<[f64; 2]>,
    /// One-core (thread CPU) and wall time of the diagnosis [s].
    pub cpu_s: f64,
    pub wall_s: f64,
    /// Time to generate the case [s].
    pub generate_s: f64,
    pub error: Option<String>,
    pub right: bool,
    /// For a case without effect: the mean `z^2` of flexid's
    /// measured FRF against the world's exact response of the true plant ([`world_z2`]).
    pub world_z2: Option<f64>,
}

/// A check of the world itself (and of flexid's estimator) on a case without any effect,
/// whatever the excitation: the mean over the lines of both levels of
/// `|H - H_true|^2 / var`, `H` and `var` flexid's estimate of the recordings (periodic,
/// stepped blocks or local polynomial), `H_true` the world's exact sampled response of the
/// true plant (alias sum). Noise alone gives the `F(2, d)` mean: about 1.3 with variances
/// from 5 periods, 1.125 for the local polynomial's 9 degrees of freedom; a world that
/// disagreed with its own truth, or an estimator whose variance does not hold, would give
/// far more. `None` for cases with an effect.
pub fn world_z2(truth: &Truth, recs: &[flexid::recording::Recording]) -> Option<f64> {
    if !truth.sizes.is_empty() {
        return None;
    }
    let (mut s, mut n) = (0.0, 0usize);
    for rec in recs {
        let e = flexid::analysis::estimate_frf(rec, None).ok()?;
        for k in 0..e.frf.freq_hz.len() {
            let (f, h, v) = (e.frf.freq_hz[k], e.frf.h[k], e.frf.var[k]);
            if v.is_finite() && v > 0.0 {
                let m = super::analytic::sampled_reading(&truth.plant, rec.sample_rate_hz, f, 100);
                s += (h - m).norm_sqr() / v;
                n += 1;
            }
        }
    }
    (n > 0).then(|| s / n as f64)
}

/// Whether two ranges `[lo, hi]` overlap.
pub fn overlaps(a: [f64; 2], b: [f64; 2]) -> bool {
    a[0] <= b[1] && a[1] >= b[0]
}

/// The group's rule: A, B and E the verdict; C both effects among those named; D
/// `unexplained` with a band overlapping where the cause acts (`bands`: the cores of the
/// diagnosis's bands, where the error is at least half its largest: a band whose
/// significant range shades the whole spectrum overlaps any cause and points at none); a
/// cause the data cannot show asks for `none`. For D, `amplitude_dependent_mode` counts as
/// `unexplained`: it is the verdict `unexplained` refined by the evidence that a mode moves
/// with the level (no library effect is named).
pub fn right(truth: &Truth, verdict: &str, effects: &[String], bands: &[[f64; 2]]) -> bool {
    match truth.group {
        Group::A | Group::B if truth.no_steady_state && verdict == "unexplained" => true,
        Group::A | Group::B | Group::E => truth.verdict.as_deref() == Some(verdict),
        // a pair neither of whose effects the data can show asks for `none`
        Group::C if truth.effects.is_empty() => verdict == "none",
        Group::C => truth.effects.iter().all(|e| effects.contains(e)),
        Group::D if truth.verdict.as_deref() == Some("none") => verdict == "none",
        // `amplitude_dependent_mode` is `unexplained` with its evidence (no candidate
        // explains the gap, and a mode moves with the level): not a library name
        Group::D => {
            matches!(verdict, "unexplained" | "amplitude_dependent_mode")
                && truth
                    .band_hz
                    .is_some_and(|t| bands.iter().any(|b| overlaps(*b, t)))
        }
    }
}

/// The outcome of a diagnosis (or its error) on a case.
pub fn outcome(
    truth: Truth,
    d: Result<&Diagnosis, String>,
    cpu_s: f64,
    wall_s: f64,
    generate_s: f64,
    world_z2: Option<f64>,
) -> Outcome {
    match d {
        Ok(d) => {
            let verdict = d.verdict.name().to_string();
            let effects: Vec<String> = d.effects.iter().map(|s| s.effect.name().into()).collect();
            let bands: Vec<[f64; 2]> = d
                .gap
                .bands
                .iter()
                .map(|(b, _)| [b.core_lo_hz, b.core_hi_hz])
                .collect();
            let ok = right(&truth, &verdict, &effects, &bands);
            Outcome {
                truth,
                verdict,
                effects,
                before_db: d.gap.before_rms_db,
                after_db: d.gap.after_rms_db,
                bands_hz: bands,
                cpu_s,
                wall_s,
                generate_s,
                error: None,
                right: ok,
                world_z2,
            }
        }
        Err(e) => Outcome {
            truth,
            verdict: "error".into(),
            effects: vec![],
            before_db: f64::NAN,
            after_db: f64::NAN,
            bands_hz: vec![],
            cpu_s,
            wall_s,
            generate_s,
            error: Some(e),
            right: false,
            world_z2,
        },
    }
}

/// The share of the excited band (in log frequency) that `bands` cover together: 1 when
/// they shade the whole spectrum, which points at nothing.
pub fn coverage(bands: &[[f64; 2]], band_hz: [f64; 2]) -> f64 {
    let (lo, hi) = (band_hz[0].max(1e-9).ln(), band_hz[1].max(1e-9).ln());
    let mut v: Vec<(f64, f64)> = bands
        .iter()
        .map(|b| (b[0].max(1e-9).ln().max(lo), b[1].max(1e-9).ln().min(hi)))
        .filter(|(a, b)| b >= a)
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut total, mut end) = (0.0, f64::NEG_INFINITY);
    for (a, b) in v {
        let a = a.max(end);
        if b > a {
            total += b - a;
        }
        end = end.max(b);
    }
    if hi > lo {
        total / (hi - lo)
    } else {
        0.0
    }
}

/// A visibility as a case line shows it: one decimal, or `chaos` where the effect's
/// response at every size tried was not periodic ([`f64::MAX`], too large to measure).
fn visibility_text(v: f64) -> String {
    if v >= f64::MAX {
        "chaos".into()
    } else {
        format!("{v:.1}")
    }
}

/// One line per case.
pub fn case_line(o: &Outcome) -> String {
    let t = &o.truth;
    let m = &t.measurement;
    let mut s = format!(
        "{} {:36} seed {:6} {}m {:.0}kHz {:12} x{:.0} {:2}b vis {:>5}: {:12}",
        t.group.name(),
        t.class,
        t.seed,
        t.masses,
        m.fs_hz / 1000.0,
        m.excitation.kind.name(),
        m.noise_factor,
        m.encoder_bits,
        visibility_text(t.visibility),
        o.verdict
    );
    if o.effects.len() > 1 {
        let _ = write!(s, " [{}]", o.effects.join("+"));
    }
    // an effect the recordings' own scatter hides is not required (truth `none`)
    let measured: Vec<String> = t
        .sizes
        .iter()
        .filter_map(|z| z.visibility_measured.map(visibility_text))
        .collect();
    if !measured.is_empty() {
        let _ = write!(s, " (vis by the records' scatter {})", measured.join(", "));
    }
    if let Some(e) = &o.error {
        let _ = write!(s, " ({e})");
    } else {
        let _ = write!(s, " gap {:.2} -> {:.2} dB", o.before_db, o.after_db);
        // the ratio only where there was a gap to shrink (no NaN or infinity printed)
        if o.before_db > 0.0 && o.after_db.is_finite() {
            let _ = write!(s, " ({:.2})", o.after_db / o.before_db);
        }
        if t.group == Group::D {
            let bands: Vec<String> = o
                .bands_hz
                .iter()
                .take(4)
                .map(|b| format!("{:.0}-{:.0}", b[0], b[1]))
                .collect();
            let tb = t.band_hz.unwrap_or([f64::NAN, f64::NAN]);
            let _ = write!(
                s,
                " bands [{}{}] cause {:.0}-{:.0} Hz",
                bands.join(" "),
                if o.bands_hz.len() > 4 { " ..." } else { "" },
                tb[0],
                tb[1]
            );
        }
    }
    if let Some(z) = o.world_z2 {
        let _ = write!(s, " [world z2 {z:.2}]");
    }
    let _ = write!(
        s,
        " | {:.2} s one core, gen {:.1} s {}",
        o.cpu_s,
        o.generate_s,
        if o.right { "ok" } else { "WRONG" }
    );
    s
}

fn median_max(v: &[f64]) -> Option<(f64, f64)> {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    s.sort_by(f64::total_cmp);
    Some((*s.get(s.len() / 2)?, *s.last()?))
}

/// The verdict columns: the library's effects, `amplitude_dependent_mode` (`amplit`),
/// `unexplained`, `error`.
fn columns() -> Vec<&'static str> {
    EFFECTS
        .iter()
        .copied()
        .chain(["amplitude_dependent_mode", "unexplained", "error"])
        .collect()
}

fn short(c: &str) -> String {
    c.chars().take(6).collect()
}

/// The report: per group its table and confusion matrix, the gap ratios, the timing, the
/// right answers per measurement axis, and the summary. Returns the text and whether every
/// group that ran met its target.
pub fn report(outcomes: &[Outcome]) -> (String, bool) {
    let mut s = String::new();
    let mut all_met = true;
    let mut summary = Vec::new();
    for g in GROUPS {
        let os: Vec<&Outcome> = outcomes.iter().filter(|o| o.truth.group == g).collect();
        if os.is_empty() {
            continue;
        }
        let right = os.iter().filter(|o| o.right).count();
        let share = right as f64 / os.len() as f64;
        let met = share >= g.target();
        all_met &= met;
        summary.push(format!(
            "{} {}/{} ({:.0} %, target {:.0} %: {})",
            g.name(),
            right,
            os.len(),
            100.0 * share,
            100.0 * g.target(),
            if met { "met" } else { "MISSED" }
        ));
        let _ = writeln!(
            s,
            "\ngroup {}: {} ({} cases)",
            g.name(),
            g.describe(),
            os.len()
        );
        let cols = columns();
        let _ = write!(s, "{:38}", "class \\ verdict");
        for c in &cols {
            let _ = write!(s, " {:>6}", short(c));
        }
        let _ = writeln!(s, "  right   visib. median   one core median/max [s]");
        for class in g.classes() {
            let rows: Vec<&&Outcome> = os.iter().filter(|o| o.truth.class == class).collect();
            if rows.is_empty() {
                continue;
            }
            let _ = write!(s, "{class:38}");
            for c in &cols {
                let n = rows.iter().filter(|o| o.verdict == *c).count();
                let _ = write!(s, " {n:>6}");
            }
            let r = rows.iter().filter(|o| o.right).count();
            let vis: Vec<f64> = rows.iter().map(|o| o.truth.visibility).collect();
            let cpu: Vec<f64> = rows.iter().map(|o| o.cpu_s).collect();
            let (vm, _) = median_max(&vis).unwrap_or((f64::NAN, f64::NAN));
            let (cm, cx) = median_max(&cpu).unwrap_or((f64::NAN, f64::NAN));
            let _ = writeln!(
                s,
                "  {r:>2}/{:<2}   {vm:13.1}   {cm:.2} / {cx:.2}",
                rows.len()
            );
        }
        if g == Group::D {
            // the rule is an overlap of the bands' cores; how much of the band they cover
            let cov: Vec<f64> = os
                .iter()
                .map(|o| coverage(&o.bands_hz, o.truth.measurement.excitation.band_hz))
                .collect();
            let narrow = os
                .iter()
                .zip(&cov)
                .filter(|(o, c)| o.right && **c < 0.5)
                .count();
            if let Some((m, x)) = median_max(&cov) {
                let _ = writeln!(
                    s,
                    "the diagnosis's bands cover a median {:.0} % (max {:.0} %) of the excited band (log frequency); right with bands covering under half of it: {narrow}/{}",
                    100.0 * m,
                    100.0 * x,
                    os.len()
                );
            }
        }
        let _ = writeln!(
            s,
            "group {}: {right}/{} right ({:.1} %), target {:.0} %: {}",
            g.name(),
            os.len(),
            100.0 * share,
            100.0 * g.target(),
            if met { "met" } else { "MISSED" }
        );
    }
    // the gap ratio of every named single effect (groups A and B)
    let named: Vec<&Outcome> = outcomes
        .iter()
        .filter(|o| matches!(o.truth.group, Group::A | Group::B))
        .filter(|o| o.error.is_none() && EFFECTS[1..].contains(&o.verdict.as_str()))
        .collect();
    if !named.is_empty() {
        let _ = writeln!(
            s,
            "\ngap ratio after/before of every named single effect (A and B; target <= 0.5), by verdict:"
        );
        let mut halved_all = true;
        for e in &EFFECTS[1..] {
            let r: Vec<f64> = named
                .iter()
                .filter(|o| o.verdict == *e)
                .map(|o| o.after_db / o.before_db)
                .collect();
            let Some((med, worst)) = median_max(&r) else {
                continue;
            };
            let halved = r.iter().filter(|x| **x <= 0.5).count();
            halved_all &= halved == r.len();
            let right: Vec<f64> = named
                .iter()
                .filter(|o| o.verdict == *e && o.right)
                .map(|o| o.after_db / o.before_db)
                .collect();
            let right_halved = right.iter().filter(|x| **x <= 0.5).count();
            let _ = writeln!(
                s,
                "  {e:20} named {:3}  median {med:.3}  worst {worst:.3}  halved {halved}/{}  (right verdicts: halved {right_halved}/{})",
                r.len(),
                r.len(),
                right.len()
            );
        }
        let _ = writeln!(
            s,
            "  every named single effect halved the gap: {}",
            if halved_all { "yes" } else { "NO" }
        );
    }
    // timing
    let cpu: Vec<f64> = outcomes.iter().map(|o| o.cpu_s).collect();
    let three: Vec<f64> = outcomes
        .iter()
        .filter(|o| o.truth.masses == 3)
        .map(|o| o.cpu_s)
        .collect();
    let _ = writeln!(
        s,
        "\none-core time per diagnosis (two levels, thread CPU clock):"
    );
    if let Some((m, x)) = median_max(&cpu) {
        let _ = writeln!(s, "  all cases:    median {m:.2} s, max {x:.2} s");
    }
    if let Some((m, x)) = median_max(&three) {
        let _ = writeln!(
            s,
            "  3-mass cases: median {m:.2} s, max {x:.2} s (issue target: worst under 2 s: {})",
            if x < 2.0 { "met" } else { "MISSED" }
        );
        summary.push(format!("3-mass worst {x:.2} s one core"));
    }
    for kind in super::excitation::KINDS {
        let all: Vec<f64> = outcomes
            .iter()
            .filter(|o| o.truth.measurement.excitation.kind == kind)
            .map(|o| o.cpu_s)
            .collect();
        let three: Vec<f64> = outcomes
            .iter()
            .filter(|o| o.truth.measurement.excitation.kind == kind && o.truth.masses == 3)
            .map(|o| o.cpu_s)
            .collect();
        if let Some((m, x)) = median_max(&all) {
            let t = median_max(&three)
                .map_or("-".to_string(), |(m3, x3)| format!("{m3:.2} / {x3:.2} s"));
            let samples: Vec<f64> = outcomes
                .iter()
                .filter(|o| o.truth.measurement.excitation.kind == kind)
                .map(|o| o.truth.measurement.samples_per_level as f64)
                .collect();
            let (sm, sx) = median_max(&samples).unwrap_or((f64::NAN, f64::NAN));
            let _ = writeln!(
                s,
                "  {:13} median {m:.2} s, max {x:.2} s; 3 masses {t} (samples per level median {sm:.0}, max {sx:.0})",
                kind.name()
            );
        }
    }
    let mut slow: Vec<&Outcome> = outcomes.iter().collect();
    slow.sort_by(|a, b| b.cpu_s.total_cmp(&a.cpu_s));
    for o in slow.iter().take(3) {
        let _ = writeln!(
            s,
            "  slow: {} {} seed {} ({} masses, {}, {:.0} samples/level): {:.2} s",
            o.truth.group.name(),
            o.truth.class,
            o.truth.seed,
            o.truth.masses,
            o.truth.measurement.excitation.kind.name(),
            o.truth.measurement.samples_per_level as f64,
            o.cpu_s
        );
    }
    // right answers per measurement axis, over every group
    let _ = writeln!(s, "\nright per measurement axis (all groups):");
    let mut axis = |name: &str, key: &dyn Fn(&Outcome) -> String| {
        let mut keys: Vec<String> = outcomes.iter().map(key).collect();
        keys.sort();
        keys.dedup();
        let parts: Vec<String> = keys
            .iter()
            .map(|k| {
                let v: Vec<&Outcome> = outcomes.iter().filter(|o| key(o) == *k).collect();
                let r = v.iter().filter(|o| o.right).count();
                format!("{k} {r}/{}", v.len())
            })
            .collect();
        let _ = writeln!(s, "  {name:12} {}", parts.join(", "));
    };
    axis("excitation", &|o| {
        o.truth.measurement.excitation.kind.name().into()
    });
    axis("sample rate", &|o| {
        format!("{:.0} Hz", o.truth.measurement.fs_hz)
    });
    axis("masses", &|o| format!("{}", o.truth.masses));
    axis("noise", &|o| {
        format!("x{:.0}", o.truth.measurement.noise_factor)
    });
    axis("viscous", &|o| {
        if o.truth.nominal_motor_viscous_nms_per_rad > 0.0 {
            "yes"
        } else {
            "no"
        }
        .into()
    });
    let z: Vec<f64> = outcomes.iter().filter_map(|o| o.world_z2).collect();
    if let Some((m, x)) = median_max(&z) {
        let _ = writeln!(
            s,
            "\nthe world against its own truth (cases without effect, {} cases): mean z2 of flexid's FRF against the true plant's exact response, median {m:.2}, max {x:.2} (noise alone: 1.1-1.3)",
            z.len()
        );
        for o in outcomes
            .iter()
            .filter(|o| o.world_z2.is_some_and(|z| z > 2.0))
        {
            let _ = writeln!(
                s,
                "  beyond its noise: {} {} seed {} ({}-bit encoder): z2 {:.2}, verdict {}",
                o.truth.group.name(),
                o.truth.class,
                o.truth.seed,
                o.truth.measurement.encoder_bits,
                o.world_z2.unwrap_or(f64::NAN),
                o.verdict
            );
        }
    }
    let errors = outcomes.iter().filter(|o| o.error.is_some()).count();
    let total_right = outcomes.iter().filter(|o| o.right).count();
    let _ = writeln!(
        s,
        "\nsummary: {} | all {total_right}/{} right, {errors} errors",
        summary.join(" | "),
        outcomes.len()
    );
    (s, all_met)
}

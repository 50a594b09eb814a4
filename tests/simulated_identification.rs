//! Acceptance test of the whole identification on simulated recordings.
//!
//! Criterion (verbatim): "On simulated recordings of 2-, 3- and 4-mass chains with 1-3 %
//! noise and encoder quantisation, every inertia and stiffness comes back within 2 % of the
//! truth, with the error inside three of its reported standard deviations, in at least 19 of
//! 20 random cases."
//!
//! For each n in {2, 3, 4}, 20 seeded random cases are drawn:
//! * interlaced anti-resonance / resonance frequencies, log-uniform within about 3 .. 400 Hz,
//!   `R/AR` in [1.3, 3], neighbouring pairs at least 1.5x apart; a total inertia log-uniform
//!   in 1e-3 .. 1e-1 kg m^2; the chain is the exact inverse of those spectra
//!   ([`chain_from_spectra`]) with damping ratios of 1-5 % per coupling;
//! * fs = 2000 or 4000 Hz; a Schroeder multisine with line spacing <= AR1/10 and <= zeta_k AR_k
//!   (about two lines in the half-power width of every peak and dip), band up to
//!   2.5 x the highest resonance (< 0.4 fs), amplitude shaped for a level velocity response
//!   (1/|H| of the chain with its resonances smoothed, as from a first sweep),
//!   1 transient + 6..10 periods, peak torque scaled with the inertia;
//! * 1-3 % velocity noise, a 2^16 .. 2^20 count encoder, a random drift (initial velocity).
//!
//! The full [`analyze`] runs on each recording, with the automatic model order (what users
//! get) and, separately, with the true order given (`masses: Some(n)`). A case passes when
//! the identified chain has n bodies and every `J_i` and `c_i` is within 2 % of the truth
//! with `|error| <= 3 sigma` (reported standard deviation). The tables printed with
//! `--nocapture` show the worst relative error and the worst error in sigmas per case.

use flexid::analysis::{analyze, AnalysisOptions};
use flexid::excitation::{AmplitudeShape, MultisineDesign};
use flexid::identify::exact::{chain_from_spectra, with_coupling_damping};
use flexid::identify::fit::FitOptions;
use flexid::model::Chain;
use flexid::recording::Sidecar;
use flexid::sim::{simulate_recording, SimOptions};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::time::Instant;

const CASES: usize = 20;
const REQUIRED: usize = 19;
const REL_TOL: f64 = 0.02;
const SIGMA_TOL: f64 = 3.0;
const STARTS: usize = 8;

/// One random simulated measurement.
#[derive(Debug, Clone)]
struct Case {
    index: usize,
    chain: Chain,
    ar_hz: Vec<f64>,
    r_hz: Vec<f64>,
    zeta: Vec<f64>,
    fs: f64,
    period: usize,
    periods: usize,
    band_hi: f64,
    noise: f64,
    counts: u64,
    drift: f64,
    seed: u64,
}

fn log_uniform(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    (rng.random_range(lo.ln()..hi.ln())).exp()
}

/// Interlaced spectra of `pairs` AR/R pairs inside [3, 400] Hz.
fn draw_spectra(rng: &mut StdRng, pairs: usize) -> (Vec<f64>, Vec<f64>) {
    loop {
        let ratios: Vec<f64> = (0..pairs).map(|_| log_uniform(rng, 1.3, 3.0)).collect();
        let gaps: Vec<f64> = (1..pairs).map(|_| log_uniform(rng, 1.5, 5.0)).collect();
        let span: f64 = ratios.iter().product::<f64>() * gaps.iter().product::<f64>();
        if span > 400.0 / 3.0 {
            continue;
        }
        let mut f = log_uniform(rng, 3.0, 400.0 / span);
        let (mut ar, mut r) = (Vec::new(), Vec::new());
        for k in 0..pairs {
            if k > 0 {
                f *= gaps[k - 1];
            }
            ar.push(f);
            f *= ratios[k];
            r.push(f);
        }
        return (ar, r);
    }
}

fn draw_case(n: usize, index: usize) -> Case {
    let seed = 1000 * n as u64 + index as u64;
    let mut rng = StdRng::seed_from_u64(seed);
    let (ar_hz, r_hz) = draw_spectra(&mut rng, n - 1);
    let total_j = log_uniform(&mut rng, 1e-3, 1e-1);
    let undamped = chain_from_spectra(total_j, &ar_hz, &r_hz).expect("interlaced spectra");
    // damping ratio 1-5 % per coupling (two-body reducer formula, as the pipeline uses)
    let zeta: Vec<f64> = (0..n - 1).map(|_| rng.random_range(0.01..0.05)).collect();
    let mut chain = undamped.clone();
    for (i, z) in zeta.iter().enumerate() {
        let d = with_coupling_damping(undamped.clone(), *z).damping_nms_per_rad[i];
        chain.damping_nms_per_rad[i] = d;
    }
    let fs = if rng.random_bool(0.5) { 2000.0 } else { 4000.0 };
    // Resolve the lowest anti-resonance (df <= AR1/10) and every pair: at least about two
    // lines inside the half-power width 2 zeta f of each resonance and anti-resonance, else
    // a lightly damped peak falls between lines and its frequency (hence J and c) is only
    // loosely determined. (A period of at least 1/(zeta AR) also lets the start-up transient
    // of each mode decay within the one transient period.)
    let df_max = ar_hz
        .iter()
        .zip(&zeta)
        .map(|(f, z)| z * f)
        .fold(ar_hz[0] / 10.0, f64::min);
    let period = (fs / df_max).ceil() as usize;
    let band_hi = (2.5 * r_hz[n - 2]).min(0.4 * fs);
    let periods = rng.random_range(6..=10);
    let noise = rng.random_range(0.01..0.03);
    let counts = 1u64 << rng.random_range(16..=20);
    let drift = rng.random_range(-2.0..2.0);
    Case {
        index,
        chain,
        ar_hz,
        r_hz,
        zeta,
        fs,
        period,
        periods,
        band_hi,
        noise,
        counts,
        drift,
        seed,
    }
}

fn simulate(case: &Case) -> flexid::recording::Recording {
    let df = case.fs / case.period as f64;
    // peak torque in proportion to the inertia (a motor sized for its load): ~2 N m at
    // 0.026 kg m^2 like the demo
    let j = case.chain.total_inertia();
    let peak = 80.0 * j;
    let mut d = MultisineDesign::new(case.fs, case.period, [df, case.band_hi], peak, peak / 2.0);
    d.crest_iterations = 30;
    // Level velocity response over the band, as a technician shapes the second sweep from a
    // first one: amplitude ~ 1/|H| of the chain with its resonances smoothed away (heavy
    // coupling damping turns every AR/R pair into the step of the effective inertia). A
    // plain f^1 slope starves the low lines whenever the motor is much lighter than the
    // load: the velocity above the resonances then dominates the RMS, and so the noise.
    let smooth = with_coupling_damping(case.chain.clone(), 0.5);
    let lines =
        flexid::excitation::band_lines(case.fs, case.period, [df, case.band_hi]).expect("lines");
    let amps: Vec<f64> = lines
        .iter()
        .map(|&k| 1.0 / smooth.mobility(k as f64 * df).norm())
        .collect();
    d.amplitude = AmplitudeShape::Custom(amps);
    let ms = d.generate().expect("multisine");
    let torque = ms.repeat(case.periods + 1);
    let sidecar = Sidecar {
        excitation: Some(ms.info(case.periods, 1)),
        ..Default::default()
    };
    let opts = SimOptions {
        sample_rate_hz: case.fs,
        delay_samples: 0,
        velocity_noise_rel: case.noise,
        torque_noise_nm: 0.0,
        encoder_counts_per_rev: Some(case.counts),
        initial_velocity_rad_s: case.drift,
        seed: case.seed,
    };
    simulate_recording(&case.chain, &torque, &opts, sidecar).expect("simulation")
}

/// What one analysis gave against the truth.
#[derive(Debug)]
struct Outcome {
    masses: usize,
    worst_rel: f64,
    worst_rel_name: String,
    worst_sigma: f64,
    worst_sigma_name: String,
    pass: bool,
    error: Option<String>,
}

fn judge(case: &Case, masses: Option<usize>) -> Outcome {
    let rec = simulate(case);
    let defaults = AnalysisOptions::default();
    let opts = AnalysisOptions {
        masses,
        // fewer random starts than the default 20 keep the 120 analyses within about a
        // minute on two cores; the first start is the exact inverse of the detected spectra
        fit: FitOptions {
            starts: STARTS,
            ..defaults.fit.clone()
        },
        ..defaults
    };
    let fail = |msg: String, masses: usize| Outcome {
        masses,
        worst_rel: f64::INFINITY,
        worst_rel_name: "-".into(),
        worst_sigma: f64::INFINITY,
        worst_sigma_name: "-".into(),
        pass: false,
        error: Some(msg),
    };
    let a = match analyze(&rec, &opts) {
        Ok(a) => a,
        Err(e) => return fail(format!("analyze failed: {e}"), 0),
    };
    if std::env::var_os("FLEXID_TEST_DETAIL").is_some() {
        let d = &a.detection;
        eprintln!(
            "case {} n={}: true AR {:?} R {:?} J {:?}\n  pairs {:?}\n  rejected {:?}\n  notes {:?}\n  orders {:?}",
            case.index,
            case.chain.masses(),
            case.ar_hz,
            case.r_hz,
            case.chain.inertia_kgm2,
            d.pairs
                .iter()
                .map(|p| (p.ar_hz, p.r_hz, p.depth_db, p.height_db, p.phase_rise_deg))
                .collect::<Vec<_>>(),
            d.rejected
                .iter()
                .map(|r| (r.freq_hz, r.prominence_db, r.prominence_sigma, r.reason.clone()))
                .collect::<Vec<_>>(),
            a.notes,
            serde_json::to_string(&a.orders).unwrap_or_default(),
        );
    }
    if let Ok(range) = std::env::var("FLEXID_TEST_LINES") {
        // print measured vs true FRF on lines in "lo,hi" Hz
        let v: Vec<f64> = range.split(',').filter_map(|x| x.parse().ok()).collect();
        let sc = flexid::model::SampledChain::new(&case.chain, case.fs, 0).unwrap();
        let nr = flexid::identify::detect::normalized_response(&a.measured.frf, None, 0).unwrap();
        for i in 0..nr.freq_hz.len() {
            if nr.freq_hz[i] >= v[0] && nr.freq_hz[i] <= v[1] {
                eprintln!(
                    "  {:9.3} Hz ln|R| {:7.3} sigma_ln {:.3}",
                    nr.freq_hz[i],
                    nr.r[i].norm().ln(),
                    nr.sigma[i]
                );
            }
        }
        let f = &a.measured.frf;
        for i in 0..f.freq_hz.len() {
            if f.freq_hz[i] >= v[0] && f.freq_hz[i] <= v[1] {
                let t = sc.frf(f.freq_hz[i]);
                eprintln!(
                    "  {:9.3} Hz meas |H| {:.4e} arg {:7.2}  true |H| {:.4e} arg {:7.2}  std {:.2e}",
                    f.freq_hz[i],
                    f.h[i].norm(),
                    f.h[i].arg().to_degrees(),
                    t.norm(),
                    t.arg().to_degrees(),
                    f.var[i].sqrt()
                );
            }
        }
    }
    let Some(m) = a.model else {
        return fail("no model".into(), 0);
    };
    let n = case.chain.masses();
    if m.masses != n {
        return fail(
            format!(
                "{} bodies identified (resonances {:?} Hz)",
                m.masses,
                m.resonance_hz
                    .iter()
                    .map(|f| (f * 10.0).round() / 10.0)
                    .collect::<Vec<_>>()
            ),
            m.masses,
        );
    }
    let truth = &case.chain;
    let mut rows: Vec<(String, f64, f64, f64)> = Vec::new(); // name, got, want, std
    for i in 0..n {
        rows.push((
            format!("J{}", i + 1),
            m.inertia_kgm2[i],
            truth.inertia_kgm2[i],
            m.inertia_std_kgm2[i],
        ));
    }
    for i in 0..n - 1 {
        rows.push((
            format!("c{}", i + 1),
            m.stiffness_nm_per_rad[i],
            truth.stiffness_nm_per_rad[i],
            m.stiffness_std_nm_per_rad[i],
        ));
    }
    let mut out = Outcome {
        masses: m.masses,
        worst_rel: 0.0,
        worst_rel_name: String::new(),
        worst_sigma: 0.0,
        worst_sigma_name: String::new(),
        pass: true,
        error: None,
    };
    for (name, got, want, std) in rows {
        let err = got - want;
        let rel = (err / want).abs();
        let sig = if std > 0.0 && std.is_finite() {
            err.abs() / std
        } else {
            f64::INFINITY
        };
        if !(rel <= out.worst_rel) {
            out.worst_rel = rel;
            out.worst_rel_name = name.clone();
        }
        if !(sig <= out.worst_sigma) {
            out.worst_sigma = sig;
            out.worst_sigma_name = name;
        }
    }
    out.pass = out.worst_rel <= REL_TOL && out.worst_sigma <= SIGMA_TOL;
    if std::env::var_os("FLEXID_TEST_DETAIL").is_some() {
        let fit = a.fit.as_ref().unwrap();
        let ti = a.total_inertia.as_ref().unwrap();
        eprintln!(
            "case {} n={n}: chi2/dof {:.3}, lines {}, total J {:.4e} +- {:.1e} (true {:.4e}, {:+.2}%)\n  J  {:?}\n  sJ {:?}\n  c  {:?}\n  sc {:?}",
            case.index,
            fit.chi2_per_dof,
            fit.lines_used,
            ti.j_kgm2,
            ti.std_kgm2,
            truth.total_inertia(),
            100.0 * (ti.j_kgm2 / truth.total_inertia() - 1.0),
            m.inertia_kgm2.iter().zip(&truth.inertia_kgm2).map(|(g, w)| format!("{:+.2}%", 100.0 * (g / w - 1.0))).collect::<Vec<_>>(),
            m.inertia_std_kgm2.iter().zip(&truth.inertia_kgm2).map(|(g, w)| format!("{:.2}%", 100.0 * g / w)).collect::<Vec<_>>(),
            m.stiffness_nm_per_rad.iter().zip(&truth.stiffness_nm_per_rad).map(|(g, w)| format!("{:+.2}%", 100.0 * (g / w - 1.0))).collect::<Vec<_>>(),
            m.stiffness_std_nm_per_rad.iter().zip(&truth.stiffness_nm_per_rad).map(|(g, w)| format!("{:.2}%", 100.0 * g / w)).collect::<Vec<_>>(),
        );
    }
    out
}

fn fmt_hz(v: &[f64]) -> String {
    v.iter()
        .map(|f| format!("{f:.1}"))
        .collect::<Vec<_>>()
        .join("/")
}

/// Run the 20 cases of an n-mass chain; print the table; return the passes.
fn run(n: usize, masses: Option<usize>) -> usize {
    let t0 = Instant::now();
    let label = if masses.is_some() { "fixed" } else { "auto" };
    let mut lines = vec![format!(
        "\n== {n}-mass chains, {label} order ==\n{:>4} {:>5} {:>6} {:>5} {:>5} {:>7} {:>4} {:>24} {:>24} {:>6} {:>4} {:>9} {:>8} {:>4}",
        "case", "fs", "df", "per", "noise", "enc", "drft", "AR [Hz]", "R [Hz]", "zeta%", "n^", "worst rel", "sigmas", "ok"
    )];
    let mut passes = 0;
    let only: Option<usize> = std::env::var("FLEXID_TEST_CASE")
        .ok()
        .and_then(|v| v.parse().ok());
    for index in 0..CASES {
        if only.is_some_and(|o| o != index) {
            continue;
        }
        let case = draw_case(n, index);
        let t = Instant::now();
        let o = judge(&case, masses);
        passes += usize::from(o.pass);
        let zeta_max = case.zeta.iter().cloned().fold(0.0, f64::max) * 100.0;
        let zeta_min = case.zeta.iter().cloned().fold(1.0, f64::min) * 100.0;
        lines.push(format!(
            "{:>4} {:>5} {:>6.3} {:>5} {:>4.1}% {:>5}b {:>+4.1} {:>24} {:>24} {:>2.0}-{:<2.0} {:>4} {:>6.2}% {:<2} {:>5.2} {:<2} {:>4} {:.1}s{}",
            case.index,
            case.fs,
            case.fs / case.period as f64,
            case.periods,
            100.0 * case.noise,
            case.counts.trailing_zeros(),
            case.drift,
            fmt_hz(&case.ar_hz),
            fmt_hz(&case.r_hz),
            zeta_min,
            zeta_max,
            o.masses,
            100.0 * o.worst_rel,
            o.worst_rel_name,
            o.worst_sigma,
            o.worst_sigma_name,
            if o.pass { "yes" } else { "NO" },
            t.elapsed().as_secs_f64(),
            o.error.map(|e| format!("  {e}")).unwrap_or_default()
        ));
    }
    lines.push(format!(
        "{n}-mass, {label} order: {passes}/{CASES} pass ({:.1} s)",
        t0.elapsed().as_secs_f64()
    ));
    // one print so that the tables of parallel tests do not interleave
    println!("{}", lines.join("\n"));
    passes
}

#[test]
fn two_mass_chains_automatic_order() {
    let p = run(2, None);
    assert!(p >= REQUIRED, "2-mass, automatic order: {p}/{CASES} pass");
}

#[test]
fn three_mass_chains_automatic_order() {
    let p = run(3, None);
    assert!(p >= REQUIRED, "3-mass, automatic order: {p}/{CASES} pass");
}

#[test]
fn four_mass_chains_automatic_order() {
    let p = run(4, None);
    assert!(p >= REQUIRED, "4-mass, automatic order: {p}/{CASES} pass");
}

#[test]
#[ignore = "supplementary (the true order given); run with --ignored"]
fn two_mass_chains_true_order() {
    let p = run(2, Some(2));
    assert!(p >= REQUIRED, "2-mass, true order given: {p}/{CASES} pass");
}

#[test]
#[ignore = "supplementary (the true order given); run with --ignored"]
fn three_mass_chains_true_order() {
    let p = run(3, Some(3));
    assert!(p >= REQUIRED, "3-mass, true order given: {p}/{CASES} pass");
}

#[test]
#[ignore = "supplementary (the true order given); run with --ignored"]
fn four_mass_chains_true_order() {
    let p = run(4, Some(4));
    assert!(p >= REQUIRED, "4-mass, true order given: {p}/{CASES} pass");
}

//! The comparison benchmark, Rust side (`scripts/bench.sh` runs it, then
//! `benches/compare.py` on the same files; see docs/benchmarks.md).
//!
//! It simulates the embedded 3-mass SCARA axis (exact ZOH, 1 % velocity noise, 20-bit
//! encoder), writes the data sets to `--out DIR` as raw little-endian `f64` files with a
//! `meta.json`, and times on the calling thread (one core):
//!
//! * Welch H1 with coherence on a long white-noise record (`welch_h1`);
//! * the periodic estimator on a multisine with many periods (`estimate_periodic`);
//! * the 60-start 3-mass fit (`fit_chain`, one thread) on the periodic FRF.
//!
//! Its results (H1, coherence, the periodic FRF with variances, the fitted chain, and the
//! fit's weighted residual vector at reference points) are written next to the data so
//! that the Python side can check that it computes the same numbers.
//!
//! Arguments: `[--quick] [--out DIR] [--serve]` (other arguments, e.g. cargo's `--bench`,
//! are ignored). With `--serve` it then answers timing requests on stdin (one run of `h1`,
//! `periodic` or `fit` per line), so that `benches/compare.py --rust EXE` can alternate
//! the two sides run by run.

use flexid::excitation::{AmplitudeShape, MultisineDesign};
use flexid::frf::{differenced_velocity, estimate_periodic, welch_h1, Frf, FrfKind};
use flexid::identify::fit::{fit_chain, start_parameters, weighted_residuals, FitOptions};
use flexid::model::Chain;
use flexid::sim::{simulate_position, SimOptions};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use serde_json::json;
use std::hint::black_box;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

const FS: f64 = 2000.0;
/// H1: a white-noise record of 2^20 samples (8.7 min at 2 kHz), 8192-sample Hann segments
/// with 50 % overlap (255 segments).
const H1_SAMPLES: usize = 1 << 20;
const H1_NPERSEG: usize = 8192;
const H1_OVERLAP: usize = 4096;
/// Periodic: 8000-sample periods (0.25 Hz lines), 0.25-800 Hz (3200 lines), 1 transient + 64 steady.
const MS_PERIOD: usize = 8000;
const MS_PERIODS: usize = 64;
const MS_TRANSIENT: usize = 1;
const FIT_STARTS: usize = 60;

fn truth() -> Chain {
    // plants/scara_shoulder.toml
    Chain::new(
        vec![3.614e-3, 5.098e-3, 17.188e-3],
        vec![2.906e4, 5.706],
        vec![0.47, 0.018],
    )
    .expect("valid chain")
}

/// The initial chain of the fit: the truth detuned by 10-25 % (J, c) and a factor 2-3 (d),
/// like an exact inverse from detected peaks would be off.
fn initial(t: &Chain) -> Chain {
    let f = |v: &[f64], k: &[f64]| v.iter().zip(k).map(|(a, b)| a * b).collect::<Vec<_>>();
    Chain::new(
        f(&t.inertia_kgm2, &[1.15, 0.85, 1.10]),
        f(&t.stiffness_nm_per_rad, &[0.80, 1.25]),
        f(&t.damping_nms_per_rad, &[3.0, 0.4]),
    )
    .expect("valid chain")
}

fn sim_opts(seed: u64) -> SimOptions {
    SimOptions {
        sample_rate_hz: FS,
        velocity_noise_rel: 0.01,
        encoder_counts_per_rev: Some(1 << 20),
        seed,
        ..SimOptions::default()
    }
}

fn write_f64(dir: &Path, name: &str, v: &[f64]) {
    let mut bytes = Vec::with_capacity(8 * v.len());
    for x in v {
        bytes.extend_from_slice(&x.to_le_bytes());
    }
    std::fs::write(dir.join(name), bytes).expect("write data file");
}

/// Run `f` `reps` times after one warm-up call; seconds per call and the last result.
fn time<T>(reps: usize, mut f: impl FnMut() -> T) -> (Vec<f64>, T) {
    let mut out = black_box(f());
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = Instant::now();
        out = black_box(f());
        t.push(t0.elapsed().as_secs_f64());
    }
    (t, out)
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

fn frf_columns(frf: &Frf, with_var: bool) -> Vec<f64> {
    let mut v: Vec<f64> = frf.h.iter().map(|h| h.re).collect();
    v.extend(frf.h.iter().map(|h| h.im));
    if with_var {
        v.extend(&frf.var);
    }
    v.extend(frf.coherence.as_ref().expect("coherence"));
    v
}

/// Max relative error of J1..Jn, c1..c(n-1) against the truth.
fn param_error(c: &Chain, t: &Chain) -> f64 {
    c.inertia_kgm2
        .iter()
        .zip(&t.inertia_kgm2)
        .chain(c.stiffness_nm_per_rad.iter().zip(&t.stiffness_nm_per_rad))
        .map(|(a, b)| (a / b - 1.0).abs())
        .fold(0.0, f64::max)
}

fn theta(c: &Chain) -> Vec<f64> {
    c.inertia_kgm2
        .iter()
        .chain(&c.stiffness_nm_per_rad)
        .chain(&c.damping_nms_per_rad)
        .map(|v| v.ln())
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .map_or_else(|| PathBuf::from("target/bench/data"), PathBuf::from);
    std::fs::create_dir_all(&out).expect("create output directory");
    let (reps_fast, reps_fit) = if quick { (5, 2) } else { (30, 5) };
    let chain = truth();
    let log = |s: String| {
        eprintln!("bench (rust): {s}");
        let _ = std::io::stderr().flush();
    };

    // ---- H1 on white noise ----
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let normal = Normal::new(0.0, 0.5).expect("normal");
    let u_h1: Vec<f64> = (0..H1_SAMPLES).map(|_| normal.sample(&mut rng)).collect();
    let pos = simulate_position(&chain, &u_h1, &sim_opts(11)).expect("simulate");
    let y_h1 = differenced_velocity(&pos, FS);
    write_f64(&out, "h1_u.f64", &u_h1);
    write_f64(&out, "h1_y.f64", &y_h1);
    let (t_h1, h1) = time(reps_fast, || {
        welch_h1(&u_h1, &y_h1, FS, H1_NPERSEG, H1_OVERLAP).expect("welch")
    });
    write_f64(&out, "h1_rust.f64", &frf_columns(&h1, false));
    log(format!(
        "H1 {} samples: median {:.2} ms",
        H1_SAMPLES,
        1e3 * median(&t_h1)
    ));

    // ---- periodic estimator on a multisine ----
    let mut d = MultisineDesign::new(FS, MS_PERIOD, [0.25, 800.0], 2.0, 1.0);
    d.crest_iterations = 30;
    d.amplitude = AmplitudeShape::PowerLaw { exponent: 1.0 };
    let ms = d.generate().expect("multisine");
    let info = ms.info(MS_PERIODS, MS_TRANSIENT);
    let u_ms = ms.repeat(MS_PERIODS + MS_TRANSIENT);
    let pos = simulate_position(&chain, &u_ms, &sim_opts(12)).expect("simulate");
    let y_ms = differenced_velocity(&pos, FS);
    write_f64(&out, "ms_u.f64", &u_ms);
    write_f64(&out, "ms_y.f64", &y_ms);
    let (t_per, per) = time(reps_fast, || {
        estimate_periodic(&u_ms, &y_ms, &info, FS, FrfKind::DifferencedVelocity).expect("periodic")
    });
    write_f64(&out, "per_rust.f64", &frf_columns(&per, true));
    log(format!(
        "periodic {} x {} samples, {} lines: median {:.2} ms",
        MS_PERIODS + MS_TRANSIENT,
        MS_PERIOD,
        info.excited_lines.len(),
        1e3 * median(&t_per)
    ));

    // ---- the 60-start 3-mass fit on the periodic FRF ----
    let frf = per;
    let mut fit_in: Vec<f64> = frf.freq_hz.clone();
    fit_in.extend(frf.h.iter().map(|h| h.re));
    fit_in.extend(frf.h.iter().map(|h| h.im));
    fit_in.extend(&frf.var);
    write_f64(&out, "fit_frf.f64", &fit_in);
    let init = initial(&chain);
    let opts = FitOptions {
        starts: FIT_STARTS,
        threads: 1,
        ..FitOptions::default()
    };
    let starts = start_parameters(&init, &opts).expect("starts");
    write_f64(&out, "fit_starts.f64", &starts.concat());
    // the fit's own residual vector at reference points, for the Python residual check
    let r_truth = weighted_residuals(&frf, &chain, &opts).expect("residuals at the truth");
    let r_init = weighted_residuals(&frf, &init, &opts).expect("residuals at the start");
    write_f64(&out, "fit_res_truth.f64", &r_truth);
    write_f64(&out, "fit_res_init.f64", &r_init);
    let (t_fit, fit) = time(reps_fit, || fit_chain(&frf, &init, &opts).expect("fit"));
    let err = param_error(&fit.chain, &chain);
    log(format!(
        "fit {} starts, {} lines: median {:.1} ms, cost {:.6e}, max param error {:.3e}",
        FIT_STARTS,
        fit.lines_used,
        1e3 * median(&t_fit),
        fit.cost,
        err
    ));
    let r_best = weighted_residuals(&frf, &fit.chain, &opts).expect("residuals at the optimum");
    write_f64(&out, "fit_res_best.f64", &r_best);

    let patience = opts.max_iter.div_ceil(fit.params + 1).max(1);
    let meta = json!({
        "quick": quick,
        "sample_rate_hz": FS,
        "threads": 1,
        "h1": {
            "samples": H1_SAMPLES, "nperseg": H1_NPERSEG, "overlap": H1_OVERLAP,
            "window": "hann", "detrend": "constant", "lines": h1.len(),
            "rust_times_s": t_h1,
        },
        "periodic": {
            "period_samples": MS_PERIOD, "periods": MS_PERIODS,
            "transient_periods": MS_TRANSIENT, "excited_lines": info.excited_lines,
            "rust_times_s": t_per,
        },
        "fit": {
            "masses": chain.masses(), "params": fit.params, "starts": FIT_STARTS,
            "lines": fit.lines_used,
            "truth_theta": theta(&chain), "init_theta": theta(&init),
            "ftol": 1e-10, "xtol": 1e-8, "gtol": 1e-10,
            "max_evaluations": patience * (fit.params + 1),
            "rust_times_s": t_fit,
            "rust_theta": theta(&fit.chain),
            "rust_cost": fit.cost,
            "rust_param_error": err,
            "rust_starts_converged": fit.starts_converged,
            "rust_evaluations_total": fit.evaluations_total,
        },
    });
    std::fs::write(
        out.join("meta.json"),
        serde_json::to_string_pretty(&meta).expect("json"),
    )
    .expect("write meta.json");
    log(format!("data and results in {}", out.display()));

    if args.iter().any(|a| a == "--serve") {
        // Interleaved timing (benches/compare.py --rust): one timed run per request, so
        // that the two sides alternate within one process lifetime each.
        serve(|what| match what {
            "h1" => seconds(|| welch_h1(&u_h1, &y_h1, FS, H1_NPERSEG, H1_OVERLAP).expect("welch")),
            "periodic" => seconds(|| {
                estimate_periodic(&u_ms, &y_ms, &info, FS, FrfKind::DifferencedVelocity)
                    .expect("periodic")
            }),
            "fit" => seconds(|| fit_chain(&frf, &init, &opts).expect("fit")),
            _ => None,
        });
    }
}

/// Seconds of one call of `f`.
fn seconds<T>(f: impl FnOnce() -> T) -> Option<f64> {
    let t0 = Instant::now();
    black_box(f());
    Some(t0.elapsed().as_secs_f64())
}

/// Answers timing requests on stdin, one a line (`h1`, `periodic`, `fit`; `quit` or end
/// of input ends): prints `ready`, then one line per request with the seconds of one run
/// (`error` for an unknown request).
fn serve(mut run: impl FnMut(&str) -> Option<f64>) {
    use std::io::BufRead;
    let stdout = std::io::stdout();
    let say = |s: String| {
        let mut o = stdout.lock();
        let _ = writeln!(o, "{s}");
        let _ = o.flush();
    };
    say("ready".into());
    for line in std::io::stdin().lock().lines() {
        let Ok(line) = line else { break };
        let what = line.trim();
        if what == "quit" {
            break;
        }
        match run(what) {
            Some(t) => say(format!("{t:e}")),
            None => say("error".into()),
        }
    }
}

//! The withheld-effect benchmark: for each of the eight classes (including `none`), random
//! 3-mass axes with one effect of random size, two excitation amplitudes, simulated by the
//! fine-step RK4 `PlantSim`; recordings and a truth file written to a temporary directory,
//! the diagnosis run on the recordings alone (the library's `diagnose`, as `flexid
//! diagnose` calls it), then the truth read back for the confusion matrix, the per-class gap
//! ratio and the timing.
//!
//!     cargo bench --bench withheld_effect -- [CASES_PER_CLASS] [--quick] [--class NAME] [--seed S] [--viscous]
//!
//! `--viscous`: every plant has viscous friction from the motor to the ground (corner
//! 0.3-3 Hz), which the nominal model must carry without naming an effect.
//!
//! With `WITHHELD_TRUTH_GAP` set, each backlash, hardening and friction case also prints the
//! gap that the *true* chain and effect leave when simulated by the diagnosis's own
//! simulator (`search::sim_model`): the floor a fit of that effect can reach on the case.
//!
//! Exit status 1 when a class misses 90 % correct or (except `none`) its worst gap ratio
//! (after/before) exceeds 0.5.

#[path = "../tests/common/withheld.rs"]
mod withheld;

use flexid::diagnose::{diagnose, DiagnoseOptions};
use flexid::recording::read_recording;
use withheld::{generate_with, Variation, CLASSES};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let var = Variation {
        viscous: args.iter().any(|a| a == "--viscous"),
    };
    let mut per_class: usize = if quick { 3 } else { 20 };
    let mut only: Option<String> = None;
    let mut seed0: u64 = 1000;
    let mut i = 0;
    while i < args.len() {
        match args[i].as_str() {
            "--class" => {
                only = args.get(i + 1).cloned();
                i += 1;
            }
            "--seed" => {
                seed0 = args[i + 1].parse().unwrap();
                i += 1;
            }
            a if a.parse::<usize>().is_ok() => per_class = a.parse().unwrap(),
            _ => {}
        }
        i += 1;
    }
    let dir = std::env::temp_dir().join(format!("flexid-withheld-{}", std::process::id()));
    let classes: Vec<&str> = CLASSES
        .iter()
        .copied()
        .filter(|c| only.as_deref().is_none_or(|o| o == *c))
        .collect();
    // one column more than the classes: the verdict `unexplained`
    let mut confusion = vec![vec![0usize; CLASSES.len() + 1]; CLASSES.len()];
    let mut ratios: Vec<Vec<f64>> = vec![Vec::new(); CLASSES.len()];
    let mut times = Vec::new();
    let mut cpu_times = Vec::new();
    // per class: one-core time of each case, and the per-stage one-core times
    let mut class_cpu: Vec<Vec<f64>> = vec![Vec::new(); CLASSES.len()];
    let mut class_stages: Vec<Vec<(&'static str, f64)>> = vec![Vec::new(); CLASSES.len()];
    for class in &classes {
        let ci = CLASSES.iter().position(|c| c == class).unwrap();
        for k in 0..per_class {
            let seed = seed0 + 100 * ci as u64 + k as u64;
            let cdir = dir.join(format!("{class}-{k}"));
            let case = generate_with(class, seed, &cdir, var);
            // the diagnosis sees the recordings only
            let recs: Vec<_> = case
                .recordings
                .iter()
                .map(|p| read_recording(p).unwrap())
                .collect();
            let t = std::time::Instant::now();
            let c0 = thread_cpu_s();
            let d = diagnose(
                &recs,
                &DiagnoseOptions {
                    masses: 3,
                    spring_substeps: std::env::var("WITHHELD_SPRING_SUBSTEPS")
                        .ok()
                        .and_then(|v| v.parse().ok())
                        .unwrap_or(DiagnoseOptions::default().spring_substeps),
                    cpu_clock: Some(flexid::rt::clock::thread_cpu_ns),
                    ..DiagnoseOptions::default()
                },
            );
            let secs = t.elapsed().as_secs_f64();
            let cpu = thread_cpu_s() - c0;
            times.push(secs);
            cpu_times.push(cpu);
            class_cpu[ci].push(cpu);
            let truth: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&case.truth_path).unwrap()).unwrap();
            let want = truth["effect"].as_str().unwrap();
            match d {
                Ok(d) => {
                    let vi = CLASSES
                        .iter()
                        .position(|c| *c == d.verdict)
                        .unwrap_or(CLASSES.len());
                    confusion[ci][vi] += 1;
                    // the gap after the *true* effect's fit when the verdict is wrong is not
                    // claimed: the ratio is the one the diagnosis reports
                    let r = d.gap.after_rms_db / d.gap.before_rms_db;
                    ratios[ci].push(r);
                    let top: Vec<String> = d
                        .ranking
                        .iter()
                        .take(3)
                        .map(|r| format!("{}:{:.0}", r.effect, r.score))
                        .collect();
                    class_stages[ci].extend(d.stage_cpu_s.iter().copied());
                    let stages: Vec<String> = d
                        .stage_cpu_s
                        .iter()
                        .map(|(n, t)| format!("{}:{t:.2}", &n[..n.len().min(6)]))
                        .collect();
                    println!(
                        "{want:20} seed {seed:5} -> {:20} gap {:.3} -> {:.3} dB ({:.3}) chi2r {:.2} {} [{}] wall {secs:.2} s, one core {cpu:.2} s [{}]",
                        d.verdict,
                        d.gap.before_rms_db,
                        d.gap.after_rms_db,
                        r,
                        d.residual.reduced_chi2,
                        if d.residual.nonlinear { "NL" } else { "L" },
                        top.join(" "),
                        stages.join(" ")
                    );
                    if std::env::var_os("WITHHELD_TRUTH_GAP").is_some() {
                        if let Some(a) = truth_gap(&recs, &truth) {
                            println!(
                                "    truth leaves {a:.3} dB ({:.3} of the gap before)",
                                a / d.gap.before_rms_db
                            );
                            if let Some(w) = &d.winner {
                                println!("    fit {:?} chi2 {:.0}", w.lin.chain, w.chi2);
                            }
                        }
                    }
                    if std::env::var_os("WITHHELD_VERBOSE").is_some() {
                        println!("{}", truth);
                        println!("{}", flexid::report::diagnosis::render(&d));
                    }
                }
                Err(e) => println!("{want:20} seed {seed:5} -> error {e}"),
            }
            if std::env::var_os("WITHHELD_KEEP").is_none() {
                let _ = std::fs::remove_dir_all(&cdir);
            }
        }
    }
    if std::env::var_os("WITHHELD_KEEP").is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    println!("\nconfusion matrix (rows: truth, columns: verdict)");
    print!("{:20}", "");
    for c in CLASSES {
        print!(" {:>6}", &c[..c.len().min(6)]);
    }
    print!(" {:>6}", "unexpl");
    println!("  correct");
    let mut ok = true;
    for (ci, c) in CLASSES.iter().enumerate() {
        let n: usize = confusion[ci].iter().sum();
        if n == 0 {
            continue;
        }
        print!("{c:20}");
        for v in &confusion[ci] {
            print!(" {v:>6}");
        }
        let frac = confusion[ci][ci] as f64 / n as f64;
        println!("  {:5.1} %", 100.0 * frac);
        ok &= frac >= 0.9;
    }
    println!("\ngap ratio after/before (diagnosis's verdict), per class: median / worst");
    for (ci, c) in CLASSES.iter().enumerate() {
        let Some((med, worst)) = median_max(&ratios[ci]) else {
            continue;
        };
        println!("{c:20} {med:.3} / {worst:.3}");
        if *c != "none" {
            ok &= worst <= 0.5;
        }
    }
    // the speed target: one two-level 3-mass diagnosis under 2 s on one core. The
    // diagnosis is single-threaded; its thread's CPU time is the one-core time (the wall
    // time is inflated when the machine is shared), both reported against the target
    const TARGET_S: f64 = 2.0;
    println!("\none-core time per case and class (target {TARGET_S} s): median / max, ratio to the target; per stage: median [s]");
    for (ci, c) in CLASSES.iter().enumerate() {
        let Some((med, max)) = median_max(&class_cpu[ci]) else {
            continue;
        };
        let mut names: Vec<&str> = Vec::new();
        for (n, _) in &class_stages[ci] {
            if !names.contains(n) {
                names.push(n);
            }
        }
        let stages: Vec<String> = names
            .iter()
            .map(|n| {
                let v: Vec<f64> = class_stages[ci]
                    .iter()
                    .filter(|(m, _)| m == n)
                    .map(|s| s.1)
                    .collect();
                let med = median_max(&v).map_or(f64::NAN, |m| m.0);
                format!("{}:{med:.2}", &n[..n.len().min(6)])
            })
            .collect();
        println!(
            "{c:20} {med:.2} / {max:.2} s  ({:.2} / {:.2} x target)  [{}]",
            med / TARGET_S,
            max / TARGET_S,
            stages.join(" ")
        );
    }
    for (what, t) in [("CPU (one core)", &cpu_times), ("wall", &times)] {
        if let Some((med, max)) = median_max(t) {
            println!(
                "diagnosis time per case (2 levels, 3 masses), {what}: median {med:.2} s, max {max:.2} s; median/target {:.2}, max/target {:.2} (target {TARGET_S} s)",
                med / TARGET_S,
                max / TARGET_S
            );
        }
    }
    let speed_ok = median_max(&cpu_times).is_some_and(|(_, m)| m < TARGET_S);
    println!(
        "speed target (every case under {TARGET_S} s of one core): {}",
        if speed_ok { "met" } else { "MISSED" }
    );
    // A benchmark reports; the always-run assertions are in tests/withheld_effect.rs.
    // FLEXID_BENCH_STRICT=1 turns a missed target into a failure (for acceptance runs).
    println!(
        "\ntargets (>= 90 % right per class, gap halved for every class but none): {}",
        if ok { "met" } else { "MISSED" }
    );
    if !ok && std::env::var("FLEXID_BENCH_STRICT").is_ok_and(|v| v == "1") {
        std::process::exit(1);
    }
}

/// The systematic RMS gap [dB] of the true chain with the true effect, simulated by the
/// diagnosis's simulator on the recordings (`None` for the linear effects and `none`).
fn truth_gap(recs: &[flexid::recording::Recording], truth: &serde_json::Value) -> Option<f64> {
    use flexid::diagnose::{lti::LinExt, nlsim::Nl, prepare, rms_parts, search::sim_model};
    let v = |k: &str| -> Vec<f64> {
        truth["chain"][k]
            .as_array()
            .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
            .unwrap_or_default()
    };
    let chain = flexid::model::Chain::new(
        v("inertia_kgm2"),
        v("stiffness_nm_per_rad"),
        v("damping_nms_per_rad"),
    )
    .ok()?;
    let k = truth["coupling"].as_u64().unwrap_or(0) as usize;
    let mut lin = LinExt::nominal(chain);
    let nl = match truth["effect"].as_str()? {
        "backlash" => Nl::Backlash {
            k,
            g: truth["half_gap_rad"].as_f64()?,
        },
        "hardening_stiffness" => Nl::Hardening {
            k,
            xref: truth["x_ref_rad"].as_f64()?,
        },
        "coulomb_friction" => {
            lin.motor_b = truth["viscous_nms_per_rad"].as_f64().unwrap_or(0.0);
            Nl::Friction {
                tc: truth["coulomb_nm"].as_f64()?,
            }
        }
        _ => return None,
    };
    let data = prepare(
        recs,
        &DiagnoseOptions {
            masses: 3,
            ..DiagnoseOptions::default()
        },
    )
    .ok()?;
    let model = sim_model(&data, &lin, nl, false)?;
    Some(rms_parts(&data, &model).0)
}

/// Median and maximum (None when empty).
fn median_max(v: &[f64]) -> Option<(f64, f64)> {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    Some((*s.get(s.len() / 2)?, *s.last()?))
}

/// CPU time of the calling thread [s].
fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid out-pointer to a timespec
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if r != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + 1e-9 * ts.tv_nsec as f64
}

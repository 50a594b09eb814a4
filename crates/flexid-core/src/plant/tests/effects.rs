//! Each effect's physical signature against an independent small computation.

use super::*;
use crate::sim::{simulate_position, SimOptions};
use crate::Complex64;

/// A fractional delay shifts the response by exactly `delay_s`: the reference is the exact
/// ZOH simulation at ten times the rate (each command held for ten fine samples), where the
/// delay is a whole number of samples.
#[test]
fn fractional_delay_shifts_the_response_by_delay_s() {
    let fs = 1000.0;
    let torque = multisine(500, &[2, 9, 31, 77, 160], 3);
    let chain = chain3();
    let mut spec = PlantSpec::linear(chain.clone());
    spec.effects.time_delay = Some(TimeDelay { delay_s: 2.3e-3 });
    let got = simulate_positions(&spec, &torque, fs, 60, 1).unwrap();
    let fine: Vec<f64> = torque.iter().flat_map(|&t| [t; 10]).collect();
    let opts = SimOptions {
        sample_rate_hz: 10.0 * fs,
        delay_samples: 23,
        ..Default::default()
    };
    let want: Vec<f64> = simulate_position(&chain, &fine, &opts)
        .unwrap()
        .into_iter()
        .step_by(10)
        .collect();
    let e = rel_err(&got, &want);
    assert!(e < 1e-6, "rel err {e:e}");
    // and a delay 0.1 cycle shorter or longer is clearly worse
    for d in [2.2e-3, 2.4e-3] {
        spec.effects.time_delay = Some(TimeDelay { delay_s: d });
        let other = simulate_positions(&spec, &torque, fs, 60, 1).unwrap();
        let eo = rel_err(&other, &want);
        assert!(eo > 100.0 * e, "delay {d}: {eo:e} vs {e:e}");
    }
}

/// Motor velocity over command in steady state at `f_hz` (whole periods at the end).
fn steady_gain(
    spec: &PlantSpec,
    fs: f64,
    f_hz: f64,
    periods: usize,
    substeps: u32,
) -> (Complex64, Vec<AxisSample>) {
    let p = (fs / f_hz).round() as usize;
    assert_eq!(p as f64 * f_hz, fs, "whole samples per period");
    let n = p * periods;
    let torque: Vec<f64> = (0..n)
        .map(|k| (2.0 * PI * k as f64 / p as f64).sin())
        .collect();
    let mut sim = PlantSim::new(spec, fs, substeps, 1).unwrap();
    let s: Vec<AxisSample> = run(&mut sim, &torque).collect();
    let last = n - 10 * p;
    let v: Vec<f64> = s[last..].iter().map(|a| a.velocity_rad_s).collect();
    (dft(&v, 10.0) / dft(&torque[last..], 10.0), s)
}

#[test]
fn first_order_current_loop_filters_the_command() {
    let (fs, fc) = (20_000.0, 200.0);
    let mut spec = PlantSpec::linear(chain2());
    spec.effects.current_loop = Some(CurrentLoop {
        bandwidth_hz: fc,
        order: 1,
        damping_ratio: 0.7,
    });
    for f in [50.0, 200.0, 800.0] {
        let (g, samples) = steady_gain(&spec, fs, f, 60, 10);
        let w = 2.0 * PI * f;
        // torque held over a sample: fundamental (1 - e^{-jwT}) / (jwT)
        let zoh = (1.0 - Complex64::from_polar(1.0, -w / fs)) / Complex64::new(0.0, w / fs);
        let want = chain2().mobility(f) / Complex64::new(1.0, f / fc) * zoh;
        assert!(
            (g - want).norm() < 2e-3 * want.norm(),
            "{f} Hz: {g} vs {want}"
        );
        // the sampled torque obeys the exact first-order recursion
        let a = (-2.0 * PI * fc / fs).exp();
        let p = (fs / f).round() as usize;
        let mut tau = 0.0;
        for (k, s) in samples.iter().enumerate() {
            assert!(
                (s.torque_nm - tau).abs() < 1e-8,
                "sample {k}: {} vs {tau}",
                s.torque_nm
            );
            tau = a * tau + (1.0 - a) * (2.0 * PI * k as f64 / p as f64).sin();
        }
    }
}

#[test]
fn second_order_current_loop_filters_the_command() {
    let (fs, fc, zeta) = (20_000.0, 300.0, 0.4);
    let mut spec = PlantSpec::linear(chain2());
    spec.effects.current_loop = Some(CurrentLoop {
        bandwidth_hz: fc,
        order: 2,
        damping_ratio: zeta,
    });
    for f in [100.0, 250.0, 800.0] {
        let (g, _) = steady_gain(&spec, fs, f, 60, 10);
        let w = 2.0 * PI * f;
        let wc = 2.0 * PI * fc;
        let zoh = (1.0 - Complex64::from_polar(1.0, -w / fs)) / Complex64::new(0.0, w / fs);
        let lp = wc * wc / Complex64::new(wc * wc - w * w, 2.0 * zeta * wc * w);
        let want = chain2().mobility(f) * lp * zoh;
        assert!(
            (g - want).norm() < 2e-3 * want.norm(),
            "{f} Hz: {g} vs {want}"
        );
    }
}

/// Inside the gap the motor moves as a lone inertia J1 (`T t^2 / (2 J1)`), the load stays
/// put; once the gap closes the load is dragged along.
#[test]
fn backlash_leaves_the_motor_alone_until_the_gap_closes() {
    let (fs, g, t) = (2000.0, 1e-3, 0.01);
    let chain = chain2();
    let j1 = chain.inertia_kgm2[0];
    let mut spec = PlantSpec::linear(chain.clone());
    spec.effects.backlash = Some(Backlash {
        coupling: 0,
        half_gap_rad: g,
    });
    let mut sim = PlantSim::new(&spec, fs, 10, 1).unwrap();
    let t_close = (2.0 * g * j1 / t).sqrt(); // 20 ms
    let samples: Vec<AxisSample> = run(&mut sim, &vec![t; 200]).collect();
    let mut checked = 0;
    for s in &samples {
        let free = t * s.time_s * s.time_s / (2.0 * j1);
        if s.time_s <= t_close {
            assert!((s.position_rad - free).abs() < 1e-12 + 1e-9 * free, "{s:?}");
            assert_eq!(s.load_position_rad, 0.0);
            checked += 1;
        } else if s.time_s > 2.0 * t_close {
            assert!(s.position_rad < 0.8 * free, "{s:?}");
            assert!(s.load_position_rad > 0.0);
        }
    }
    assert!(checked >= 40);
    // without the gap the motor never moves as a lone inertia
    let lin: Vec<f64> = simulate_positions(&PlantSpec::linear(chain), &[t; 40], fs, 10, 1).unwrap();
    assert!((lin[39] - t * (39.0 / fs).powi(2) / (2.0 * j1)).abs() > 1e-2 * lin[39]);
}

/// Under a constant torque (damped transients) the spring carries `J2 a`, `a = T/J`: its
/// deflection solves the cubic `c x (1 + (x/x_ref)^2) = T J2 / J` (Newton, here).
#[test]
fn hardening_spring_deflects_by_the_cubic_law() {
    let chain = Chain::new(vec![2e-3, 6e-3], vec![800.0], vec![2.0]).unwrap();
    let (c, x_ref, t) = (800.0, 5e-4, 1.0);
    let load = t * chain.inertia_kgm2[1] / chain.total_inertia();
    let mut spec = PlantSpec::linear(chain);
    spec.effects.hardening_stiffness = Some(Hardening {
        coupling: 0,
        x_ref_rad: x_ref,
    });
    let mut sim = PlantSim::new(&spec, 2000.0, 20, 1).unwrap();
    for _ in 0..400 {
        sim.step(t);
    }
    let x = sim.body_positions()[0] - sim.body_positions()[1];
    let mut want = load / c;
    for _ in 0..50 {
        let f = c * want * (1.0 + (want / x_ref).powi(2)) - load;
        want -= f / (c * (1.0 + 3.0 * (want / x_ref).powi(2)));
    }
    assert!(
        (x - want).abs() < 1e-6 * want,
        "deflection {x:e}, cubic law {want:e}"
    );
    assert!(want < 0.6 * load / c, "the cubic term matters here");
}

/// Lowest frequency of a 2-mass chain with gravity `mgl` on body 2 (a grounding spring):
/// the eigenvalues of `M^-1 K`, `K = [[c, -c], [-c, c + mgl]]`.
fn pendulum_hz(j1: f64, j2: f64, c: f64, mgl: f64) -> f64 {
    let k = nalgebra::Matrix2::new(c / j1, -c / j1, -c / j2, (c + mgl) / j2);
    let ev = k.complex_eigenvalues();
    ev.iter().map(|l| l.re).fold(f64::INFINITY, f64::min).sqrt() / (2.0 * PI)
}

/// Zero-crossing frequency [Hz] of `x` sampled at `fs`.
fn crossing_hz(x: &[f64], fs: f64) -> f64 {
    let mut t = Vec::new();
    for k in 1..x.len() {
        if x[k - 1] < 0.0 && x[k] >= 0.0 {
            t.push((k - 1) as f64 + x[k - 1] / (x[k - 1] - x[k]));
        }
    }
    assert!(t.len() >= 3, "{} crossings", t.len());
    (t.len() - 1) as f64 / ((t[t.len() - 1] - t[0]) / fs)
}

#[test]
fn gravity_swings_at_the_pendulum_frequency() {
    let chain = Chain::new(vec![2e-3, 6e-3], vec![8000.0], vec![0.5]).unwrap();
    let mgl = 0.08;
    let mut spec = PlantSpec::linear(chain);
    spec.effects.gravity = Some(Gravity {
        m_g_l_nm: mgl,
        offset_rad: 0.0,
    });
    let fs = 1000.0;
    let mut torque = vec![0.0; 12_000];
    torque[..10].fill(0.005); // a kick: ~6 mrad swing
    let mut sim = PlantSim::new(&spec, fs, 10, 1).unwrap();
    let load: Vec<f64> = run(&mut sim, &torque)
        .map(|s| s.load_position_rad)
        .collect();
    let amp = load.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(amp > 1e-3 && amp < 2e-2, "amplitude {amp}");
    let f = crossing_hz(&load[100..], fs);
    let want = pendulum_hz(2e-3, 6e-3, 8000.0, mgl);
    let rigid = (mgl / 8e-3).sqrt() / (2.0 * PI);
    assert!((f - want).abs() < 1e-3 * want, "{f} Hz vs {want} Hz");
    assert!(
        (f - rigid).abs() < 1e-2 * rigid,
        "{f} Hz vs sqrt(mgl/J)/2pi = {rigid} Hz"
    );
}

/// The extra mode makes the plant the extended chain: same samples as its exact ZOH
/// simulation, and the free vibration peaks at the extended chain's resonances.
#[test]
fn extra_mode_has_the_extended_chains_resonances() {
    let fs = 2000.0;
    let mut spec = PlantSpec::linear(chain2());
    spec.effects.extra_mode = Some(ExtraMode {
        inertia_kgm2: 1e-3,
        stiffness_nm_per_rad: 2000.0,
        damping_nms_per_rad: 0.01,
    });
    let ext = spec.extended_chain();
    assert_eq!(ext.masses(), 3);
    let torque = multisine(1000, &[3, 17, 40, 81, 150, 333], 3);
    let want = simulate_position(
        &ext,
        &torque,
        &SimOptions {
            sample_rate_hz: fs,
            ..Default::default()
        },
    )
    .unwrap();
    let got = simulate_positions(&spec, &torque, fs, 40, 1).unwrap();
    assert!(rel_err(&got, &want) < 1e-6);

    // free vibration of the undamped extended chain after a one-cycle kick
    for c in [&mut spec.chain.damping_nms_per_rad] {
        c.fill(0.0);
    }
    spec.effects
        .extra_mode
        .as_mut()
        .unwrap()
        .damping_nms_per_rad = 0.0;
    let mut torque = vec![0.0; 40_000];
    torque[0] = 1.0;
    let mut sim = PlantSim::new(&spec, fs, 10, 1).unwrap();
    let v: Vec<f64> = run(&mut sim, &torque).map(|s| s.velocity_rad_s).collect();
    let n = v.len() as f64;
    let hann: Vec<f64> = v
        .iter()
        .enumerate()
        .map(|(k, x)| x * (1.0 - (2.0 * PI * k as f64 / n).cos()))
        .collect();
    let res = spec.extended_chain().resonances_hz();
    assert_eq!(res.len(), 2);
    for &fr in &res {
        // peak of |DFT| on a grid of 0.01 bins around the predicted resonance
        let bin = fr * n / fs;
        let (mut best, mut at) = (0.0, 0.0);
        for i in -300..=300 {
            let b = bin + i as f64 * 0.01;
            let m = dft(&hann, b).norm();
            if m > best {
                best = m;
                at = b;
            }
        }
        let f_peak = at * fs / n;
        assert!(
            (f_peak - fr).abs() < 2e-4 * fr + 0.01,
            "peak {f_peak} Hz vs resonance {fr} Hz"
        );
    }
}

#[test]
fn torque_noise_has_the_requested_size_and_is_seeded() {
    let chain = Chain::new(vec![1e-2], vec![], vec![]).unwrap();
    let mut spec = PlantSpec::linear(chain);
    spec.effects.torque_noise_nm = 0.1;
    let fs = 1000.0;
    let zeros = vec![0.0; 20_000];
    let mut sim = PlantSim::new(&spec, fs, 4, 7).unwrap();
    let a: Vec<AxisSample> = run(&mut sim, &zeros).collect();
    // each cycle adds w T / J to the velocity
    let dv: Vec<f64> = a
        .windows(2)
        .map(|w| w[1].velocity_rad_s - w[0].velocity_rad_s)
        .collect();
    let mean = dv.iter().sum::<f64>() / dv.len() as f64;
    let sd = (dv.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / dv.len() as f64).sqrt();
    let want = 0.1 / fs / 1e-2;
    assert!((sd / want - 1.0).abs() < 0.03, "sd {sd} vs {want}");
    assert!(mean.abs() < 4.0 * want / (dv.len() as f64).sqrt());
    assert!(
        a.iter().all(|s| s.torque_nm == 0.0),
        "noise is not motor torque"
    );
    sim.reset();
    let b: Vec<AxisSample> = run(&mut sim, &zeros).collect();
    assert_eq!(a, b, "reset replays the same noise");
    let mut other = PlantSim::new(&spec, fs, 4, 8).unwrap();
    let c: Vec<AxisSample> = run(&mut other, &zeros).collect();
    assert_ne!(a, c, "another seed, other noise");
}

#[test]
fn encoder_quantises_the_motor_position_only() {
    let torque = multisine(1000, &[3, 17, 40], 2);
    let mut spec = PlantSpec::linear(chain3());
    let mut sim = PlantSim::new(&spec, 1000.0, 8, 1).unwrap();
    let clean: Vec<AxisSample> = run(&mut sim, &torque).collect();
    spec.effects.encoder_counts_per_rev = Some(4096);
    let mut sim = PlantSim::new(&spec, 1000.0, 8, 1).unwrap();
    let q = 2.0 * PI / 4096.0;
    let quant: Vec<AxisSample> = run(&mut sim, &torque).collect();
    let mut off = 0.0f64;
    for (a, b) in quant.iter().zip(&clean) {
        assert!(((a.position_rad / q) - (a.position_rad / q).round()).abs() < 1e-9);
        assert!((a.position_rad - b.position_rad).abs() <= q / 2.0 + 1e-12);
        assert_eq!(a.velocity_rad_s, b.velocity_rad_s);
        assert_eq!(a.load_position_rad, b.load_position_rad);
        off = off.max((a.position_rad - b.position_rad).abs());
    }
    assert!(off > q / 10.0);
    // uniform rounding error: RMS q / sqrt(12)
    let rms = (quant
        .iter()
        .zip(&clean)
        .map(|(a, b)| (a.position_rad - b.position_rad).powi(2))
        .sum::<f64>()
        / quant.len() as f64)
        .sqrt();
    assert!(
        (rms / (q / 12f64.sqrt()) - 1.0).abs() < 0.05,
        "rms {rms}, q {q}"
    );
}

/// Stored plus kinetic energy of a free undamped plant with hardening, backlash and gravity.
fn energy(sim: &PlantSim, spec: &PlantSpec) -> f64 {
    let ch = spec.extended_chain();
    let (p, v) = (sim.body_positions(), sim.body_velocities());
    let mut e: f64 = ch
        .inertia_kgm2
        .iter()
        .zip(v)
        .map(|(j, w)| 0.5 * j * w * w)
        .sum();
    for (i, c) in ch.stiffness_nm_per_rad.iter().enumerate() {
        let mut x = p[i + 1] - p[i];
        if let Some(b) = &spec.effects.backlash {
            if b.coupling == i {
                x = x.signum() * (x.abs() - b.half_gap_rad).max(0.0);
            }
        }
        let mut u = 0.5 * c * x * x;
        if let Some(h) = &spec.effects.hardening_stiffness {
            if h.coupling == i {
                u += 0.25 * c * x.powi(4) / h.x_ref_rad.powi(2);
            }
        }
        e += u;
    }
    if let Some(g) = &spec.effects.gravity {
        e += g.m_g_l_nm * (1.0 - (p[p.len() - 1] + g.offset_rad).cos());
    }
    e
}

#[test]
fn free_undamped_plant_conserves_energy_and_damping_dissipates_it() {
    let chain = Chain::new(vec![2e-3, 4e-3, 9e-3], vec![600.0, 9000.0], vec![0.0, 0.0]).unwrap();
    let mut spec = PlantSpec::linear(chain);
    spec.effects.hardening_stiffness = Some(Hardening {
        coupling: 0,
        x_ref_rad: 2e-3,
    });
    spec.effects.gravity = Some(Gravity {
        m_g_l_nm: 0.5,
        offset_rad: 0.0,
    });
    let mut sim = PlantSim::new(&spec, 2000.0, 20, 1).unwrap();
    for _ in 0..20 {
        sim.step(0.5);
    }
    let e0 = energy(&sim, &spec);
    let mut worst = 0.0f64;
    for _ in 0..4000 {
        sim.step(0.0);
        worst = worst.max((energy(&sim, &spec) / e0 - 1.0).abs());
    }
    assert!(worst < 1e-6, "energy drift {worst:e}");

    // backlash (a kink in the force) costs accuracy but not conservation
    spec.effects.backlash = Some(Backlash {
        coupling: 1,
        half_gap_rad: 1e-4,
    });
    let mut sim = PlantSim::new(&spec, 2000.0, 20, 1).unwrap();
    for _ in 0..20 {
        sim.step(0.5);
    }
    let e0 = energy(&sim, &spec);
    for _ in 0..4000 {
        sim.step(0.0);
    }
    let drift = (energy(&sim, &spec) / e0 - 1.0).abs();
    assert!(drift < 1e-3, "energy drift with backlash {drift:e}");

    // with dampers the free energy never grows
    spec.chain.damping_nms_per_rad = vec![0.05, 0.3];
    let mut sim = PlantSim::new(&spec, 2000.0, 20, 1).unwrap();
    for _ in 0..20 {
        sim.step(0.5);
    }
    let mut prev = energy(&sim, &spec);
    let start = prev;
    for _ in 0..2000 {
        sim.step(0.0);
        let e = energy(&sim, &spec);
        assert!(e <= prev * (1.0 + 1e-9), "{e} > {prev}");
        prev = e;
    }
    assert!(prev < 0.99 * start, "{prev} vs {start}");
}

/// With an offset, gravity loads the axis from the start: holding `T = mgl sin(offset)`
/// the chain settles with the load at 0 and the spring deflected by `T/c`.
#[test]
fn gravity_offset_is_held_by_its_static_torque() {
    let chain = Chain::new(vec![2e-3, 6e-3], vec![800.0], vec![2.0]).unwrap();
    let (mgl, offset) = (0.4, 0.3);
    let mut spec = PlantSpec::linear(chain);
    spec.effects.gravity = Some(Gravity {
        m_g_l_nm: mgl,
        offset_rad: offset,
    });
    // viscous motor friction damps the swing (it carries no torque at rest)
    spec.effects.friction = Some(Friction {
        coulomb_nm: 0.0,
        viscous_nms_per_rad: 0.05,
    });
    let hold = mgl * f64::sin(offset);
    let mut sim = PlantSim::new(&spec, 2000.0, 10, 1).unwrap();
    for _ in 0..8000 {
        sim.step(hold);
    }
    let p = sim.body_positions();
    assert!(p[1].abs() < 1e-9, "load at {}", p[1]);
    assert!(
        ((p[0] - p[1]) - hold / 800.0).abs() < 1e-9,
        "deflection {}",
        p[0] - p[1]
    );
    // without the holding torque the arm falls towards hanging down (-offset)
    sim.reset();
    for _ in 0..200 {
        sim.step(0.0);
    }
    assert!(sim.sample().load_position_rad < -0.01);
}

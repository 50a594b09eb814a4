//! The diagnosis's independent world (`tests/world`, run in full by
//! `benches/diagnose_world.rs`), checked cheaply: its simulator against independent
//! computations of the same physics, its sub-step count, the causes outside the library
//! against the bands declared for them, the sizing, and the cases' reproducibility from
//! their seeds (at 1, 2, 4 and 8 kHz).

mod world;

use flexid::model::{Chain, SampledChain};
use flexid::Complex64;
use world::analytic;
use world::plant::{Coupling, Gravity, Law, LowPass, Notch, Plant, Resonator};
use world::simulator::Sim;
use world::substeps::{stiffest, substeps, Peaks};

/// A 3-body chain with well damped couplings (3-4 %) and features between 40 and 300 Hz,
/// so that a few periods settle it.
fn test_chain() -> Chain {
    Chain::new(vec![2e-3, 6e-3, 1.5e-2], vec![2.4e3, 900.0], vec![0.3, 0.2]).unwrap()
}

/// The simulated response `(lines [Hz], torque -> differenced position)` of `plant` at
/// `fs`, noise-free, on a random-phase multisine of 1 Hz lines from 2 Hz to 0.4 fs, the
/// last of `periods` periods analysed.
fn simulated(plant: &Plant, fs: f64, steps: usize, periods: usize) -> (Vec<f64>, Vec<Complex64>) {
    use flexid::excitation::{MultisineDesign, PhaseDesign};
    let n = fs as usize;
    let mut d = MultisineDesign::new(fs, n, [2.0, 0.4 * fs], 1.0, 0.01);
    d.phases = PhaseDesign::Random { seed: 7 };
    let m = d.generate().unwrap();
    let u = m.repeat(periods);
    let y: Vec<f64> = Sim::new(plant, fs, steps, 0, true)
        .run(&u)
        .iter()
        .map(|s| s.position_rad)
        .collect();
    let last = (periods - 1) * n;
    let dft = |x: &dyn Fn(usize) -> f64, k: usize| {
        (0..n)
            .map(|j| {
                Complex64::from_polar(
                    x(j),
                    -2.0 * std::f64::consts::PI * (k * j) as f64 / n as f64,
                )
            })
            .sum::<Complex64>()
    };
    let lines: Vec<usize> = m.excited_lines.iter().copied().step_by(7).collect();
    let h = lines
        .iter()
        .map(|&k| {
            let yd = dft(&|j| (y[last + j] - y[last + j - 1]) * fs, k);
            let uf = dft(&|j| u[last + j], k);
            yd / uf
        })
        .collect();
    (lines.iter().map(|&k| k as f64).collect(), h)
}

fn worst_relative(a: &[Complex64], b: &[Complex64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a / b - 1.0).norm())
        .fold(0.0, f64::max)
}

/// The frequency-domain solve `(K - w^2 M + j w C)^-1` gives the chain's own mobility.
#[test]
fn analytic_response_is_the_chains_mobility() {
    let mut rng = <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(3);
    for n in 2..=5 {
        let c = world::plants::random_chain(&mut rng, n, 3.0, 600.0, 2.0);
        let p = Plant::nominal(&c, 0.0, 20);
        for f in [0.7, 3.3, 17.0, 95.0, 410.0, 1300.0] {
            let mine = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f)
                * analytic::body_positions(&p, f)[0];
            let rel = (mine / c.mobility(f) - 1.0).norm();
            assert!(rel < 1e-9, "{n} bodies at {f} Hz: {rel:e}");
        }
    }
}

/// The simulator, noise-free, reproduces the chain's exact ZOH-sampled response
/// (`flexid::model::SampledChain`) within 2e-5 relative on every line checked, at 1, 2
/// and 8 kHz (the worst is next to the top resonance: RK4's frequency error), and the
/// alias sum used for the extensions below agrees with it within 1e-9.
#[test]
fn simulator_matches_the_exact_sampled_chain() {
    let c = test_chain();
    let p = Plant::nominal(&c, 0.0, 20);
    for fs in [1000.0, 2000.0, 8000.0] {
        let steps = substeps(&p, fs, &Peaks::default());
        let (f, h) = simulated(&p, fs, steps, 4);
        let sc = SampledChain::new(&c, fs, 0).unwrap();
        let exact: Vec<Complex64> = f.iter().map(|&f| sc.frf(f)).collect();
        let alias: Vec<Complex64> = f
            .iter()
            .map(|&f| analytic::sampled_differenced(&p, fs, f, 3000))
            .collect();
        let e = worst_relative(&h, &exact);
        let a = worst_relative(&alias, &exact);
        println!("{fs} Hz, {steps} sub-steps: simulator {e:.2e}, alias sum {a:.2e}");
        assert!(e < 2e-5, "{fs} Hz: simulator off by {e:e}");
        assert!(a < 1e-9, "{fs} Hz: alias sum off by {a:e}");
    }
}

/// Every linear part of the world (motor viscous friction, gravity at small angles, an
/// extra body, a fractional delay, a notch, a current loop, the encoder's shaft, the
/// position low-pass) simulated against its exact sampled
/// response from the frequency domain (alias sum), within 5e-5 relative.
#[test]
fn simulator_matches_the_analytic_response_of_every_linear_part() {
    let c = test_chain();
    let fs = 2000.0;
    let base = Plant::nominal(&c, 0.2, 20);
    let mut parts: Vec<(&str, Plant)> = Vec::new();
    let mut with = |name, f: &dyn Fn(&mut Plant)| {
        let mut p = base.clone();
        f(&mut p);
        parts.push((name, p));
    };
    with("viscous", &|_| {});
    with("gravity", &|p| {
        p.gravity = Some(Gravity {
            body: 2,
            m_g_l_nm: 30.0,
            bearing_damping_nms_per_rad: 0.5,
        })
    });
    with("extra body", &|p| {
        p.inertia_kgm2.push(4e-3);
        p.couplings.push(Coupling {
            stiffness_nm_per_rad: 600.0,
            damping_nms_per_rad: 0.15,
            law: Law::Linear,
        });
    });
    with("delay", &|p| p.drive.delay_s = 1.37 / fs);
    with("notch", &|p| {
        p.drive.notch = Some(Notch {
            centre_hz: 150.0,
            pole_damping_ratio: 0.3,
            zero_damping_ratio: 0.03,
        })
    });
    with("current loop", &|p| {
        p.drive.current_loop = Some(LowPass {
            order: 2,
            bandwidth_hz: 500.0,
            damping_ratio: 0.7,
        })
    });
    with("encoder shaft", &|p| {
        p.sensor.shaft = Some(Resonator {
            frequency_hz: 400.0,
            damping_ratio: 0.05,
        })
    });
    with("position low-pass", &|p| {
        p.sensor.lowpass = Some(LowPass {
            order: 1,
            bandwidth_hz: 200.0,
            damping_ratio: 0.7,
        })
    });
    for (name, p) in &parts {
        let steps = substeps(p, fs, &Peaks::default());
        let (f, h) = simulated(p, fs, steps, 5);
        let exact: Vec<Complex64> = f
            .iter()
            .map(|&f| analytic::sampled_differenced(p, fs, f, 3000))
            .collect();
        let e = worst_relative(&h, &exact);
        // the part must matter: the response differs from the chain's without it
        let without = if *name == "viscous" {
            Plant::nominal(&c, 0.0, 20)
        } else {
            base.clone()
        };
        let plain: Vec<Complex64> = f
            .iter()
            .map(|&f| analytic::sampled_differenced(&without, fs, f, 3000))
            .collect();
        let change = worst_relative(&exact, &plain);
        println!("{name}: {steps} sub-steps, off by {e:.2e} (the part changes the response by {change:.2e})");
        assert!(e < 5e-5, "{name}: off by {e:e}");
        assert!(change > 1e-2, "{name}: changes nothing ({change:e})");
    }
}

/// The sub-step count follows the highest eigenfrequency: the plain chain's is its top
/// resonance, a hardening spring at its peak deflection raises it.
#[test]
fn substeps_follow_the_highest_eigenfrequency() {
    let c = test_chain();
    let p = Plant::nominal(&c, 0.0, 20);
    let (w, _) = stiffest(&p, &Peaks::default());
    let top = c.resonances_hz().into_iter().fold(0.0, f64::max);
    assert!(
        (w / (2.0 * std::f64::consts::PI * top) - 1.0).abs() < 1e-9,
        "{w} against {top} Hz"
    );
    assert_eq!(
        substeps(&p, 1000.0, &Peaks::default()),
        (w / 1000.0 / 0.1).ceil() as usize
    );
    let mut h = p.clone();
    h.couplings[0].law = Law::Hardening { x_ref_rad: 1e-3 };
    let peaks = Peaks {
        deflection_rad: vec![2e-3, 0.0],
        position_rad: vec![],
    };
    assert!(stiffest(&h, &peaks).0 > 1.5 * w);
}

/// Halving the step converges: on a chain with every nonlinearity at once (backlash with
/// its contact ramp, a hardening coupling, Stribeck friction, cogging, a cubic ground
/// spring, gravity, the amplifier's dead zone, a fractional delay, a current loop, play in
/// the encoder's coupling), the
/// differenced position at the derived sub-step count is within 2e-3 of the RMS velocity
/// of a run at 8x the sub-steps on every sample, and each halving of the step divides that
/// by at least 8 (RK4's order 4 kept across the kinks).
#[test]
fn halving_the_substep_converges_on_every_nonlinearity() {
    use flexid::excitation::{MultisineDesign, PhaseDesign};
    use world::plant::{Cogging, Friction, GroundCubic};
    let c = test_chain();
    let fs = 1000.0;
    let rms = 0.05;
    let mut p = Plant::nominal(&c, 0.05, 20);
    let lines: Vec<f64> = (2..400).map(|k| k as f64).collect();
    let m = analytic::rms_motion(&p, &lines, rms);
    let (x0, x1) = (m.deflection_rad[0], m.deflection_rad[1]);
    p.couplings[0].law = Law::DeadZone {
        half_gap_rad: 0.5 * x0,
        contact_ramp_rad: 0.05 * x0,
    };
    p.couplings[1].law = Law::Hardening {
        x_ref_rad: 2.0 * x1,
    };
    p.friction = Some(Friction {
        coulomb_nm: 0.1 * rms,
        static_nm: 0.13 * rms,
        stribeck_rad_s: 0.01,
        regularisation_rad_s: 1e-3,
    });
    p.cogging = Some(Cogging {
        amplitude_nm: 0.01 * rms,
        periods_per_rev: 24.0,
    });
    p.ground_cubic = Some(GroundCubic {
        body: 2,
        cubic_nm_per_rad3: 1.0,
    });
    p.gravity = Some(Gravity {
        body: 2,
        m_g_l_nm: 2.0,
        bearing_damping_nms_per_rad: 0.05,
    });
    p.drive.delay_s = 0.6 / fs;
    p.drive.dead_zone_nm = 0.02 * rms;
    p.drive.current_loop = Some(LowPass {
        order: 1,
        bandwidth_hz: 300.0,
        damping_ratio: 0.7,
    });
    p.sensor.half_play_rad = 0.01 * m.position_rad[0];
    let peaks = Peaks {
        deflection_rad: m.deflection_rad.iter().map(|x| 6.0 * x).collect(),
        position_rad: m.position_rad.iter().map(|x| 6.0 * x).collect(),
    };
    let n = substeps(&p, fs, &peaks);
    let mut d = MultisineDesign::new(fs, 1000, [2.0, 400.0], 1.0, rms);
    d.phases = PhaseDesign::Random { seed: 3 };
    let u = d.generate().unwrap().repeat(2);
    let run = |k: usize| -> Vec<f64> {
        let y: Vec<f64> = Sim::new(&p, fs, k, 0, true)
            .run(&u)
            .iter()
            .map(|s| s.position_rad)
            .collect();
        y.windows(2).map(|w| (w[1] - w[0]) * fs).collect()
    };
    let reference = run(8 * n);
    let scale = (reference.iter().map(|v| v * v).sum::<f64>() / reference.len() as f64).sqrt();
    let err = |x: &[f64]| {
        x.iter()
            .zip(&reference)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
            / scale
    };
    let (e1, e2, e4) = (err(&run(n)), err(&run(2 * n)), err(&run(4 * n)));
    println!(
        "{n} sub-steps: {e1:.2e}, {}: {e2:.2e}, {}: {e4:.2e}",
        2 * n,
        4 * n
    );
    assert!(e1 < 2e-3, "{e1:e} at the derived {n} sub-steps");
    assert!(e2 < e1 / 8.0 && e4 < e2 / 8.0, "{e1:e} {e2:e} {e4:e}");
}

const DEV: u64 = 50_000;

fn spec(
    group: world::cases::Group,
    class: &'static str,
    k: usize,
    fs: Option<f64>,
) -> world::cases::Spec {
    let ci = group.classes().iter().position(|c| *c == class).unwrap();
    world::cases::Spec {
        group,
        class,
        seed: world::cases::seed_of(DEV, group, ci, k),
        fs_hz: fs,
    }
}

/// A case without an effect is the nominal chain within its own noise: the FRF that
/// flexid's periodic estimator makes of its recordings agrees with the world's exact
/// sampled response of the true plant (alias sum) with mean `z^2 = |H - H_true|^2 / var`
/// below 2.5 and median below 1.5 (noise alone: about 1.3 and 0.6-1 with variances from 5
/// periods), at each level; and the visibility's line-noise model is within 2x of the
/// estimator's scatter on full-grid designs. The first development cases of `none` and of
/// E's variations measured with a multisine, at 1 kHz, position and velocity readings.
#[test]
fn a_case_without_effect_is_the_nominal_chain_within_its_own_noise() {
    use world::cases::Group;
    use world::excitation::Kind;
    use world::generate::{measure, plan};
    let mut seen_velocity = false;
    for (group, class) in [
        (Group::A, "none"),
        (Group::E, "no_viscous"),
        (Group::E, "noise_x3"),
        (Group::E, "encoder_14bit"),
        (Group::E, "velocity_output"),
        (Group::E, "four_masses"),
    ] {
        let p = (0..20)
            .map(|k| plan(&spec(group, class, k, Some(1000.0))))
            .find(|p| {
                matches!(
                    p.design.kind,
                    Kind::OddRandom | Kind::Schroeder | Kind::RandomPhase
                )
            })
            .expect("a multisine case");
        let sigma = world::visibility::sigma_ln(&p.ctx.nominal, &p.ctx.reference);
        let reference_lines = p.ctx.reference.lines_hz.clone();
        let full_grid = p.design.kind != Kind::OddRandom;
        let dir = tempfile::tempdir().unwrap();
        let case = measure(p, dir.path());
        let t = &case.truth;
        seen_velocity |= t.plant.sensor.output == world::plant::Output::Velocity;
        for (level, path) in case.recordings.iter().enumerate() {
            let rec = flexid::recording::read_recording(path).unwrap();
            let e = flexid::analysis::estimate_frf(&rec, None).unwrap();
            let (mut z2, mut ratio) = (Vec::new(), Vec::new());
            for k in 0..e.frf.freq_hz.len() {
                let (f, h, v) = (e.frf.freq_hz[k], e.frf.h[k], e.frf.var[k]);
                if !(v.is_finite() && v > 0.0) {
                    continue;
                }
                let m = analytic::sampled_reading(&t.plant, rec.sample_rate_hz, f, 3000);
                z2.push((h - m).norm_sqr() / v);
                if let Some(i) = reference_lines.iter().position(|x| (x - f).abs() < 1e-6) {
                    ratio.push(v.sqrt() / h.norm() / sigma[level][i]);
                }
            }
            z2.sort_by(f64::total_cmp);
            ratio.sort_by(f64::total_cmp);
            let mean = z2.iter().sum::<f64>() / z2.len() as f64;
            let median = z2[z2.len() / 2];
            let r = ratio[ratio.len() / 2];
            println!(
                "{class} seed {} level {level} ({:?}, {} bits, {} masses): {} lines, z2 mean {mean:.2} median {median:.2}; scatter / model {r:.2}",
                t.seed,
                t.measurement.excitation.kind,
                t.measurement.encoder_bits,
                t.masses,
                z2.len()
            );
            assert!(
                mean < 2.5 && median < 1.5,
                "{class} seed {}: z2 mean {mean} median {median}",
                t.seed
            );
            if full_grid {
                assert!(
                    (0.5..2.0).contains(&r),
                    "{class} seed {}: scatter/model {r}",
                    t.seed
                );
            }
        }
    }
    assert!(seen_velocity);
}

/// Each cause outside the library changes the FRF where its truth file says and not far
/// outside: simulated again without noise on a multisine of other phases (the declared
/// band came from the analytic response, or a simulation on the reference phases), the
/// largest change over the lines within the declared band is at least half the largest
/// anywhere, and more than a factor 2 in frequency outside it, at most a quarter of it
/// (the band's edges are where the change falls to a tenth). The first development case
/// of each cause, at 1 kHz.
#[test]
fn each_cause_acts_in_its_declared_band() {
    use world::cases::Group;
    use world::generate::{peaks_of, plan};
    use world::visibility::{delta_of, simulated_response};
    for class in world::causes::CAUSES {
        let p = plan(&spec(Group::D, class, 0, Some(1000.0)));
        let band = p.band_hz.expect("a declared band");
        let mut r = p.ctx.reference.clone();
        r.phase_seed ^= 0x5eed;
        let without =
            simulated_response(&p.ctx.nominal, &r, &peaks_of(&p.ctx.nominal, &p.ctx)).response;
        let with = simulated_response(&p.plant, &r, &peaks_of(&p.plant, &p.ctx)).response;
        let delta = delta_of(&without, &with);
        let m: Vec<f64> = (0..r.lines_hz.len())
            .map(|k| delta.iter().map(|d| d[k].norm()).fold(0.0, f64::max))
            .collect();
        let top = m.iter().copied().fold(0.0, f64::max);
        let pick = |keep: &dyn Fn(f64) -> bool| {
            r.lines_hz
                .iter()
                .zip(&m)
                .filter(|(f, _)| keep(**f))
                .map(|(_, v)| *v)
                .fold(0.0, f64::max)
        };
        let inside = pick(&|f| f >= band[0] && f <= band[1]);
        let outside = pick(&|f| f < band[0] / 2.0 || f > 2.0 * band[1]);
        println!(
            "{class}: declared {:.1}-{:.1} Hz, visibility {:.1}; largest change {top:.3}, inside {inside:.3}, far outside {outside:.3}",
            band[0], band[1], p.visibility
        );
        assert!(p.visibility > 2.0, "{class}: visibility {}", p.visibility);
        assert!(
            inside >= 0.5 * top,
            "{class}: {inside} inside against {top}"
        );
        assert!(
            outside <= 0.25 * top,
            "{class}: {outside} outside against {top}"
        );
    }
}

/// Sizing: each library effect's full size is its typical drawn size when that is
/// visible enough, else it is enlarged until its visibility beyond the nominal model
/// reaches the target within 10 % (or the end of its range), or a drawn size that drives
/// the axis out of a periodic steady state is reduced until it does not; a third of it is less
/// visible (but for the cubic ground spring, which jumps). The first development case of
/// each effect in groups A and B, at 1 kHz.
/// A visibility for print: `f64::MAX` stands for a response that is not periodic.
fn shown(v: f64) -> String {
    if v == f64::MAX {
        "not periodic".into()
    } else {
        format!("{v:.2}")
    }
}

#[test]
fn effects_are_sized_to_their_visibility() {
    use world::cases::Group;
    use world::generate::plan;
    for class in world::effects::EFFECTS {
        let a = plan(&spec(Group::A, class, 0, Some(1000.0)));
        let s = &a.sizes[0];
        let k = world::effects::effect(
            class,
            &a.ctx,
            &mut <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(0),
        );
        let at_end = (s.full_size / k.range[1] - 1.0).abs() < 1e-9;
        println!(
            "{class}: {} typical {:.4} (visibility {}), full {:.4} (visibility {}, target {:.2}){}",
            s.size_name,
            s.typical_size,
            shown(s.typical_visibility),
            s.full_size,
            shown(s.full_visibility),
            s.target_visibility,
            if at_end { ", at the range's end" } else { "" }
        );
        if s.typical_visibility == f64::MAX {
            // the drawn size drove the axis out of a periodic steady state: smaller, and
            // periodic
            assert!(s.full_size < s.typical_size, "{class}");
            assert!(s.full_visibility < f64::MAX, "{class}");
        } else if s.typical_visibility >= s.target_visibility {
            assert_eq!(s.full_size, s.typical_size, "{class}");
        } else {
            assert!(s.full_size > s.typical_size, "{class}");
            assert!(
                at_end || (s.full_visibility / s.target_visibility).ln().abs() < 1.1f64.ln(),
                "{class}: {} for {}",
                s.full_visibility,
                s.target_visibility
            );
        }
        let b = plan(&spec(Group::B, class, 0, Some(1000.0)));
        let t = &b.sizes[0];
        assert!((t.size * 3.0 / t.full_size - 1.0).abs() < 1e-12);
        println!(
            "  a third: {:.4} (visibility {:.2} against {:.2} at full size)",
            t.size, t.visibility, t.full_visibility
        );
        // a cubic spring to the ground is not monotone: a large low-frequency swing jumps
        // (Duffing), and a third of the size can show more
        if class != "hardening_ground" {
            assert!(
                t.visibility < t.full_visibility,
                "{class}: {} against {}",
                t.visibility,
                t.full_visibility
            );
        }
    }
}

/// Group A's first case without an effect, at 1 kHz, and the noise of its reference
/// signal's lines (`sigma_ln`): the plant the visibility tests change.
fn none_case() -> (world::generate::Plan, Vec<Vec<f64>>) {
    let a = world::generate::plan(&spec(world::cases::Group::A, "none", 0, Some(1000.0)));
    let sigma = world::visibility::sigma_ln(&a.ctx.nominal, &a.ctx.reference);
    (a, sigma)
}

/// What a re-fitted nominal chain absorbs is not counted as visible: a large change of the
/// nominal chain's own parameters (a stiffness x1.25, the load x0.85, a ground damper:
/// visibility of order 200) is followed by the refit to within 1 % of its visibility against
/// the true chain, while a change no chain makes (a drive delay of a fifth of a sample)
/// keeps most of it.
#[test]
fn the_refit_nominal_chain_absorbs_chain_changes_not_a_delay() {
    use world::visibility::{delta_linear, visibility, Projector};
    let (a, sigma) = none_case();
    let (nominal, r) = (&a.ctx.nominal, &a.ctx.reference);
    let projector = Projector::new(nominal, r, sigma.clone());
    let mut chain = nominal.clone();
    chain.couplings[0].stiffness_nm_per_rad *= 1.25;
    let last = chain.inertia_kgm2.len() - 1;
    chain.inertia_kgm2[last] *= 0.85;
    chain.motor_viscous_nms_per_rad +=
        0.02 * chain.total_inertia_kgm2() * 2.0 * std::f64::consts::PI * 10.0;
    let d = delta_linear(nominal, &chain, r);
    let (before, after) = (
        visibility(&d, &sigma),
        visibility(&projector.residual(&d), &sigma),
    );
    println!("chain change: visibility {before:.1} against the true chain, {after:.3} beyond the nominal model");
    assert!(before > 20.0, "{before}");
    assert!(after < 0.01 * before, "{after} of {before}");
    let mut delayed = nominal.clone();
    delayed.drive.delay_s += 0.2 / r.fs_hz;
    let d = delta_linear(nominal, &delayed, r);
    let (before, after) = (
        visibility(&d, &sigma),
        visibility(&projector.residual(&d), &sigma),
    );
    println!(
        "delay: visibility {before:.1} against the true chain, {after:.1} beyond the nominal model"
    );
    assert!(after > 0.5 * before, "{after} of {before}");
}

/// A cause outside the library is judged beyond the nominal model and a library delay
/// (`Projector::with_delay`): a drive delay of 0.4 samples is taken by the refit to within
/// 1 % of its visibility; so is most of a low-pass on the position reading at the band's
/// top (under 5 % of its visibility beyond the chain is left: a chain and a delay mimic its
/// roll-off there), while one at a quarter of the top stays visible beyond the delay (more
/// than the line noise; its roll-off within the band is no delay). The world sizes such a cause until it shows
/// beyond the delay.
#[test]
fn a_cause_outside_the_library_is_judged_beyond_a_delay() {
    use world::plant::LowPass;
    use world::visibility::{delta_linear, visibility, Projector};
    let (a, sigma) = none_case();
    let (nominal, r) = (&a.ctx.nominal, &a.ctx.reference);
    let chain_only = Projector::new(nominal, r, sigma.clone());
    let with_delay = Projector::new(nominal, r, sigma.clone()).with_delay(r.fs_hz);
    let mut delayed = nominal.clone();
    delayed.drive.delay_s += 0.4 / r.fs_hz;
    let d = delta_linear(nominal, &delayed, r);
    let (alone, beyond) = (
        visibility(&chain_only.residual(&d), &sigma),
        visibility(&with_delay.residual(&d), &sigma),
    );
    println!("delay: visibility {alone:.2} beyond the chain, {beyond:.4} beyond a delay too");
    assert!(alone > 10.0, "{alone}");
    assert!(beyond < 0.01 * alone, "{beyond} of {alone}");
    let f_max = r.lines_hz.last().copied().unwrap();
    let beyond_of = |corner_hz: f64| {
        let mut filtered = nominal.clone();
        filtered.sensor.lowpass = Some(LowPass {
            order: 2,
            bandwidth_hz: corner_hz,
            damping_ratio: std::f64::consts::FRAC_1_SQRT_2,
        });
        let d = delta_linear(nominal, &filtered, r);
        let v = (
            visibility(&chain_only.residual(&d), &sigma),
            visibility(&with_delay.residual(&d), &sigma),
        );
        println!(
            "low-pass at {corner_hz:.1} Hz: visibility {:.2} beyond the chain, {:.2} beyond a delay too",
            v.0, v.1
        );
        v
    };
    let (alone, beyond) = beyond_of(f_max);
    assert!(alone > 10.0, "{alone}");
    assert!(beyond < 0.05 * alone, "{beyond} of {alone}");
    let (alone_q, beyond_q) = beyond_of(f_max / 4.0);
    assert!(beyond_q > 1.0, "{beyond_q}");
    assert!(beyond_q / alone_q > 2.0 * beyond / alone);
}

/// Each case is reproducible from its seed: generated twice, the recordings (CSV and
/// sidecar) and the truth file are the same bytes; the sidecar names the sample rate and
/// the excitation. The first development case of one class per group, and cases forced
/// to 1 and 8 kHz.
#[test]
fn cases_are_reproducible_from_their_seeds() {
    use world::cases::Group;
    use world::generate::generate;
    let specs = [
        spec(Group::A, "backlash", 0, None),
        spec(Group::B, "time_delay", 0, None),
        spec(Group::C, "coulomb_friction+unmodelled_mode", 0, None),
        spec(Group::D, "notch_filter", 0, None),
        spec(Group::E, "swept_sine", 0, None),
        spec(Group::A, "hardening_stiffness", 1, Some(1000.0)),
        spec(Group::A, "current_loop", 1, Some(8000.0)),
    ];
    for s in &specs {
        let (d1, d2) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let (c1, _c2) = (generate(s, d1.path()), generate(s, d2.path()));
        let mut files: Vec<_> = std::fs::read_dir(d1.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        files.sort();
        assert_eq!(files.len(), 5, "{files:?}"); // 2 x (csv + json) + truth
        for f in &files {
            let (a, b) = (
                std::fs::read(d1.path().join(f)).unwrap(),
                std::fs::read(d2.path().join(f)).unwrap(),
            );
            assert!(a == b, "{} seed {}: {f:?} differs", s.class, s.seed);
        }
        let rec = flexid::recording::read_recording(&c1.recordings[1]).unwrap();
        let fs = c1.truth.measurement.fs_hz;
        assert_eq!(rec.sample_rate_hz, fs);
        assert_eq!(rec.sidecar.sample_rate_hz, Some(fs));
        assert!(rec.sidecar.excitation.is_some());
        if let Some(f) = s.fs_hz {
            assert_eq!(fs, f);
        }
        println!(
            "{} {} seed {}: {} Hz, {:?}, {} samples per level, reproduced",
            s.group.name(),
            s.class,
            s.seed,
            fs,
            c1.truth.measurement.excitation.kind,
            rec.time_s.len()
        );
    }
}

/// An arm under gravity is measured in its linear range, as a technician would: it starts
/// at rest where it hangs and the levels keep its swing small (the world's
/// `gravity_level_scale`), so that even a slow swept or stepped sine near the swing's
/// resonance never lifts it past the horizontal (before: twelve half-turns over the top at
/// the high level). The first development gravity case measured with a sine, at 1 kHz.
#[test]
fn an_arm_under_gravity_swings_within_its_linear_range() {
    use world::cases::Group;
    use world::excitation::Kind;
    use world::generate::{measure, plan};
    let p = (0..40)
        .map(|k| plan(&spec(Group::A, "gravity", k, Some(1000.0))))
        .find(|p| matches!(p.design.kind, Kind::SweptSine | Kind::SteppedSine))
        .expect("a gravity case measured with a sine");
    let kind = p.design.kind;
    let dir = tempfile::tempdir().unwrap();
    let case = measure(p, dir.path());
    for (level, path) in case.recordings.iter().enumerate() {
        let rec = flexid::recording::read_recording(path).unwrap();
        let q = rec.position_rad.as_ref().expect("a position reading");
        let largest = q.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        println!("{kind:?} level {level}: largest motor angle {largest:.3} rad");
        assert!(
            largest < std::f64::consts::FRAC_PI_2,
            "level {level}: the arm swung to {largest} rad"
        );
    }
}

/// The world judges a sweep by the noise its recordings show. A logarithmic sweep spends
/// a time `~ 1/f` per hertz, so its estimate is noisier at the top of the band than a flat
/// multisine's of the same RMS: the flat reference's noise (what the world judged sweeps
/// by before) misses the scatter of eight further recordings (an `H1` estimate per line)
/// by more than a factor 1.6 in some sixth of the band, while the world's own measure
/// (the energy per line of the sweep, corrected by six recordings of its own,
/// `repeated_sigma_ln`) is within 1.6 of it in every sixth.
#[test]
fn the_world_judges_a_sweep_by_the_noise_its_recordings_show() {
    use world::excitation::Kind;
    use world::generate::{drawn_kind, plan};
    use world::visibility::{ln_h1_lines, repeated_sigma_ln, sigma_ln, Reference};
    let spec = (0..200)
        .map(|k| spec(world::cases::Group::A, "none", k, Some(1000.0)))
        .find(|s| drawn_kind(s) == Kind::SweptSine)
        .expect("a sweep among the draws");
    let p = plan(&spec);
    let (plant, r) = (&p.ctx.nominal, &p.ctx.reference);
    let level = 1;
    let (u, _) = p.design.generate(r.levels_rms_nm[level]);
    let runs_of = |seeds: std::ops::Range<u64>, exact: bool| -> Vec<Vec<Complex64>> {
        seeds
            .map(|seed| {
                let mut sim = Sim::new(plant, r.fs_hz, 8, seed, exact);
                sim.start_centred(&u);
                let out = sim.run(&u);
                let y: Vec<f64> = (0..out.len())
                    .map(|i| out[i].position_rad - out[i.saturating_sub(1)].position_rad)
                    .collect();
                ln_h1_lines(&u, &y, &r.lines_hz, r.fs_hz, p.design.line_spacing_hz)
            })
            .collect()
    };
    let exact = runs_of(0..1, true).remove(0);
    let own = repeated_sigma_ln(
        &runs_of(100..106, false),
        &exact,
        &sigma_ln(plant, r)[level],
    );
    let check = runs_of(1000..1008, false);
    let k = check.len() as f64;
    let var: Vec<f64> = (0..r.lines_hz.len())
        .map(|l| {
            check
                .iter()
                .map(|h| (h[l] - exact[l]).norm_sqr())
                .sum::<f64>()
                / k
        })
        .collect();
    let sixths = |sigma: &[f64]| -> Vec<f64> {
        let m = var.len() / 6;
        (0..6)
            .map(|t| {
                let mut q: Vec<f64> = (t * m..(t + 1) * m)
                    .map(|l| var[l] / (sigma[l] * sigma[l]))
                    .collect();
                q.sort_by(f64::total_cmp);
                q[q.len() / 2]
            })
            .collect()
    };
    let flat_reference = Reference {
        energy: None,
        ..r.clone()
    };
    let flat = sixths(&sigma_ln(plant, &flat_reference)[level]);
    let own = sixths(&own);
    println!("scatter of 8 recordings / the world's variance, median per sixth of the band: own {own:.2?}, flat reference {flat:.2?}");
    let within = |q: &f64| (1.0 / 1.6..1.6).contains(q);
    assert!(own.iter().all(within), "{own:?}");
    assert!(!flat.iter().all(within), "{flat:?}");
}

/// An extra body far above the band, hung on the load by a stiff spring, moves with the
/// load below its pair: to any nominal model the load's inertia grows, and nothing else
/// shows. The world's refit from the true nominal chain cannot always follow that (the
/// load's lightly damped anti-resonance moves by lines, many widths: development case A
/// unmodelled_mode 10 kept a visibility of 100 and asked for `unmodelled_mode` where the
/// mode is invisible); started also from the chain with the body merged into the load
/// (`Knob::absorbed`), it leaves nothing, and the case asks for `none`.
#[test]
fn an_extra_body_merged_into_the_load_is_absorbed_by_the_world_s_refit() {
    use world::visibility::{delta_linear, detectable, visibility, Projector};
    let a = world::generate::plan(&spec(world::cases::Group::A, "unmodelled_mode", 10, None));
    let sigma = world::visibility::sigma_ln(&a.ctx.nominal, &a.ctx.reference);
    let (nominal, r) = (&a.ctx.nominal, &a.ctx.reference);
    let n = nominal.inertia_kgm2.len();
    assert_eq!(a.plant.inertia_kgm2.len(), n + 1, "one extra body");
    let projector = Projector::new(nominal, r, sigma.clone());
    let d = delta_linear(nominal, &a.plant, r);
    let mut merged = nominal.clone();
    merged.inertia_kgm2[n - 1] += a.plant.inertia_kgm2[n];
    let (true_chain, from_nominal, with_merged) = (
        visibility(&d, &sigma),
        visibility(&projector.residual(&d), &sigma),
        visibility(&projector.residual_from(&d, &[merged]), &sigma),
    );
    println!(
        "visibility: {true_chain:.1} against the true chain, {from_nominal:.2} refitted from it, {with_merged:.4} also from the merged chain (detectable {:.2})",
        detectable(&sigma)
    );
    assert!(true_chain > 20.0, "{true_chain}");
    assert!(with_merged < detectable(&sigma), "{with_merged}");
    assert!(with_merged <= from_nominal);
    assert!(
        a.effects.is_empty(),
        "the case asks for none: {:?}",
        a.effects
    );
}

/// A case generated from its spec and diagnosed with its number of bodies.
fn diagnosed(s: &world::cases::Spec) -> (world::cases::Case, flexid::diagnose::Diagnosis) {
    use flexid::diagnose::{diagnose, DiagnoseOptions};
    let dir = tempfile::tempdir().unwrap();
    let case = world::generate::generate(s, dir.path());
    let recs: Vec<_> = case
        .recordings
        .iter()
        .map(|p| flexid::recording::read_recording(p).unwrap())
        .collect();
    let d = diagnose(
        &recs,
        &DiagnoseOptions {
            masses: case.truth.masses,
            ..DiagnoseOptions::default()
        },
    )
    .unwrap();
    (case, d)
}

/// A linear effect that dominates the gap does not hide an amplitude-dependent one beside
/// it: on dev case C 70202 (a current loop and a hardening coupling, 2 masses, 2 kHz
/// stepped sine) the hardening alone does not improve on the nominal model (its fit ends
/// above it: the loop's part of the gap is the larger), but the FRF changes between levels
/// beyond the noise, which the loop cannot explain, so the amplitude-dependent candidates
/// are tried on top of it and both are named. (C 70201 showed it until the world judged
/// stepped sines on their own spots: its hardening is now sized so that the diagnosis
/// calls it `unexplained`.)
#[test]
fn an_amplitude_dependent_effect_is_sought_beside_a_linear_one_when_the_levels_differ() {
    use world::cases::Group;
    let s = spec(Group::C, "hardening_stiffness+current_loop", 2, None);
    let (_, d) = diagnosed(&s);
    let alone = d
        .ranking
        .iter()
        .find(|r| r.effect == flexid::diagnose::Effect::HardeningStiffness);
    println!("hardening alone: {:?}", alone.map(|r| r.score));
    assert!(
        alone.is_none_or(|r| !(r.score > 0.0)),
        "{:?}",
        alone.map(|r| r.score)
    );
    let named: Vec<&str> = d.effects.iter().map(|s| s.effect.name()).collect();
    println!("seed {}: effects {named:?}", s.seed);
    assert!(named.contains(&"current_loop"), "{named:?}");
    assert!(named.contains(&"hardening_stiffness"), "{named:?}");
}

/// The hardening coupling of a case (its index and `x_ref`), diagnosed: the verdict, and
/// the fitted coupling and `x_ref`.
fn diagnose_hardening(s: &world::cases::Spec) -> ((usize, f64), String, usize, f64) {
    use world::plant::Law;
    let (case, d) = diagnosed(s);
    assert_eq!(case.truth.measurement.excitation.kind.name(), "swept_sine");
    let truth = case
        .truth
        .plant
        .couplings
        .iter()
        .enumerate()
        .find_map(|(k, c)| match c.law {
            Law::Hardening { x_ref_rad } => Some((k, x_ref_rad)),
            _ => None,
        })
        .expect("a hardening coupling");
    let verdict = d.verdict.name().to_string();
    let Some(step) = d.effects.first() else {
        return (truth, verdict, usize::MAX, f64::NAN);
    };
    let param = |name: &str| {
        step.fit
            .params
            .iter()
            .find(|p| p.name == name)
            .map_or(f64::NAN, |p| p.value)
    };
    println!(
        "seed {}: {verdict}, x_ref {:.4e} rad on coupling {} (the world's {:.4e} on {})",
        s.seed,
        param("x_ref_rad"),
        param("coupling"),
        truth.1,
        truth.0
    );
    (
        truth,
        verdict,
        param("coupling") as usize,
        param("x_ref_rad"),
    )
}

/// A hardening spring under a sweep is started from the deflection at its resonance, not
/// from the RMS over the record: on an exploration case (base 30000, not a development or
/// held-out seed; A 30309: a hardening on the second coupling of 3 masses, 2 kHz swept sine)
/// the RMS deflection's describing function put `x_ref` 8x below the spring's, every start
/// was worse than the nominal model, and the verdict was `unexplained`. Started from the
/// resonance peak as well, the fit reaches the spring's own `x_ref` on its own coupling.
#[test]
fn a_spring_under_a_sweep_is_started_from_its_resonance_deflection() {
    let s = exploration_a_from(30_000, "hardening_stiffness", 9);
    let ((coupling, x_ref), verdict, k, x) = diagnose_hardening(&s);
    assert_eq!(verdict, "hardening_stiffness", "seed {}", s.seed);
    assert_eq!(k, coupling);
    assert!((x / x_ref - 1.0).abs() < 0.2, "{x}");
}

/// A spring that jumps is found from the small-signal chain: on dev case A 50303 (2 masses,
/// a 4 kHz sweep through a hardening coupling whose resonance moves from 75 to about 200 Hz
/// at the high level) each level's linear fit put the chain far from the true one and the
/// cost of `x_ref` has a valley some 15 % wide, flat beside it: no start reached it
/// (`unexplained`). The chain fitted where the levels agree, the stiffening where they do
/// not, and the backbone's amplitude put the scan on it.
#[test]
fn a_spring_that_jumps_is_found_from_the_small_signal_chain() {
    use world::cases::Group;
    let s = spec(Group::A, "hardening_stiffness", 3, None);
    let ((coupling, x_ref), verdict, k, x) = diagnose_hardening(&s);
    assert_eq!(verdict, "hardening_stiffness", "seed {}", s.seed);
    assert_eq!(k, coupling);
    assert!((x / x_ref - 1.0).abs() < 0.2, "{x}");
}

/// An exploration case (base 900000, not a development or held-out seed) of group A.
fn exploration_a(class: &'static str, k: usize) -> world::cases::Spec {
    exploration_a_from(900_000, class, k)
}

/// The value of parameter `name` of the first effect named.
fn first_effect_param(d: &flexid_core::diagnose::Diagnosis, name: &str) -> f64 {
    d.effects[0]
        .fit
        .params
        .iter()
        .find(|p| p.name == name)
        .unwrap_or_else(|| panic!("no {name}"))
        .value
}

/// Group A's case `k` of `class` in the exploration set of seed base `base`.
fn exploration_a_from(base: u64, class: &'static str, k: usize) -> world::cases::Spec {
    use world::cases::Group;
    let ci = Group::A.classes().iter().position(|c| *c == class).unwrap();
    world::cases::Spec {
        group: Group::A,
        class,
        seed: world::cases::seed_of(base, Group::A, ci, k),
        fs_hz: None,
    }
}

/// A cubic spring to the ground is searched from the grounded chain the spectra show: on
/// exploration case A 900403 (2 masses, a 4 kHz sweep, a cubic spring on the load about
/// as stiff as the gear at the high level) the nominal chain, fitted free, put its pair
/// between the two, the cubic search from it ended at 1.1e-4 for 0.22 N m/rad³, gravity's
/// fit above the nominal model, and the verdict was `unexplained`.
#[test]
fn a_cubic_ground_spring_is_searched_from_the_grounded_chain_of_the_spectra() {
    let s = exploration_a("hardening_ground", 3);
    let (case, d) = diagnosed(&s);
    let truth = case
        .truth
        .plant
        .ground_cubic
        .as_ref()
        .expect("a cubic ground spring")
        .cubic_nm_per_rad3;
    assert_eq!(d.verdict.name(), "hardening_stiffness", "seed {}", s.seed);
    let k3 = first_effect_param(&d, "ground_k3_nm_per_rad3");
    println!("seed {}: k3 {k3:.4e} (the world's {truth:.4e})", s.seed);
    assert!((k3 / truth).ln().abs() < 2f64.ln(), "k3 {k3} for {truth}");
    assert!(
        d.gap.after_rms_db < 0.6 * d.gap.before_rms_db,
        "{:?}",
        d.gap
    );
}

/// Each family of spring starts is refined on its own: on exploration case A 900301 (2
/// masses, 2 kHz, a hardening coupling under an odd random-phase multisine) the one start
/// of lowest cost as given, refined alone, led to `backlash`; the levels' own fits reach
/// the hardening spring.
#[test]
fn each_family_of_spring_starts_is_refined() {
    let s = exploration_a("hardening_stiffness", 1);
    let (_, d) = diagnosed(&s);
    assert_eq!(d.verdict.name(), "hardening_stiffness", "seed {}", s.seed);
}

/// A strongly stiffening coupling is simulated accurately enough to be found: on
/// exploration case A 920300 (base 920000: 2 masses, a 4 kHz sweep through a resonance
/// some 5 `x_ref` deep) the held cubic torque of the old step left the bounds at the true
/// model and every hardening fit ended above the nominal model (`unexplained`); with the
/// Hermite step (`nlsim.rs`) the spring is named with `x_ref` near the world's.
#[test]
fn a_strongly_stiffening_coupling_is_simulated_to_fourth_order() {
    let s = exploration_a_from(920_000, "hardening_stiffness", 0);
    let (case, d) = diagnosed(&s);
    assert_eq!(d.verdict.name(), "hardening_stiffness", "seed {}", s.seed);
    let truth = case
        .truth
        .plant
        .couplings
        .iter()
        .find_map(|c| match c.law {
            world::plant::Law::Hardening { x_ref_rad } => Some(x_ref_rad),
            _ => None,
        })
        .expect("a hardening coupling");
    let x_ref = first_effect_param(&d, "x_ref_rad");
    println!(
        "seed {}: x_ref {x_ref:.4e} (the world's {truth:.4e})",
        s.seed
    );
    assert!(
        (x_ref / truth).ln().abs() < 1.25f64.ln(),
        "x_ref {x_ref} for {truth}"
    );
}

/// The world judges a stepped sine on the stepped sine itself: its spots are the lines
/// judged, each with the energy of its block's steady periods (`N A^2 / 4`), and the
/// noise-free simulated response of the linear nominal plant at each spot whose block has
/// settled (its last two periods agree within 1e-4) is the exact sampled response (the
/// alias sum of the differenced position, `analytic::sampled_differenced`, over `f_s`)
/// within 1e-3. Not every spot settles in the world's 3 + 4 periods: in this draw (4
/// bodies, lightly damped) 10 of 40 do, the spots from 20 Hz up change by 1e-3 to a factor
/// 10 from one period to the next; the recordings show the same transient (the
/// diagnosis's block estimator reads it as period-to-period scatter), and the world judges
/// a nonlinear effect by the ratio of two such responses.
#[test]
fn the_world_judges_a_stepped_sine_on_its_own_spots() {
    use world::excitation::Kind;
    use world::generate::{drawn_kind, plan};
    use world::substeps::Peaks;
    use world::visibility::simulated_response;
    let spec = (0..200)
        .map(|k| spec(world::cases::Group::A, "none", k, Some(1000.0)))
        .find(|s| drawn_kind(s) == Kind::SteppedSine)
        .expect("a stepped sine among the draws");
    let p = plan(&spec);
    let (plant, r) = (&p.ctx.nominal, &p.ctx.reference);
    let st = r
        .stepped
        .as_ref()
        .expect("the stepped sine in the reference");
    assert_eq!(st.len(), r.levels_rms_nm.len());
    for (i, s) in st.iter().enumerate() {
        assert_eq!(s.blocks.len(), r.lines_hz.len(), "level {i}");
        for ((b, f), e) in s.blocks.iter().zip(&r.lines_hz).zip(r.line_energy(i)) {
            assert_eq!(b.frequency_hz, *f);
            let want = (b.periods * b.period_samples) as f64 * b.amplitude_nm.powi(2) / 4.0;
            assert!(
                (e - want).abs() <= 1e-12 * want,
                "level {i} {f} Hz: {e} vs {want}"
            );
        }
    }
    let peaks = Peaks {
        deflection_rad: vec![1e-3; plant.couplings.len()],
        position_rad: vec![1e-2; plant.couplings.len() + 1],
    };
    let sim = simulated_response(plant, r, &peaks);
    for (i, (h, change)) in sim.response.iter().zip(&sim.change).enumerate() {
        let mut settled = 0;
        for ((&f, h), c) in r.lines_hz.iter().zip(h).zip(change) {
            let want = analytic::sampled_differenced(plant, r.fs_hz, f, 3000) / r.fs_hz;
            let error = ((h - want) / want).norm();
            if c.norm() < 1e-4 {
                settled += 1;
                assert!(
                    error < 1e-3,
                    "level {i}, {f} Hz: {error:e} (change {:e})",
                    c.norm()
                );
            }
        }
        println!("level {i}: {settled} of {} spots settled", h.len());
        assert!(settled >= 5, "level {i}: {settled} spots settled");
    }
}

/// A current loop is fitted from the chain behind it: on dev case A 50601 (a first-order
/// loop at 781 Hz, 3 masses, 4 kHz stepped sine) the nominal chain bends to mimic the loop
/// (its motor coupling damped 200x too little), and a loop fitted from it tied with a delay
/// (scores 192135 and 192146, both leaving a reduced chi2 of 1600 where the true model
/// leaves 0.8); from the chain identified with the reading's loop divided out
/// (`diagnose::loop_free`) the loop is named, at its corner within 1 %.
#[test]
fn a_current_loop_is_fitted_from_the_chain_behind_it() {
    use world::cases::Group;
    let s = spec(Group::A, "current_loop", 1, None);
    let (case, d) = diagnosed(&s);
    assert_eq!(
        case.truth.measurement.excitation.kind.name(),
        "stepped_sine"
    );
    let truth = case
        .truth
        .plant
        .drive
        .current_loop
        .expect("a loop in the drive");
    let fit = d.winner.as_ref().expect("a named effect");
    println!(
        "seed {}: {} {:?} (true {:.1} Hz)",
        s.seed, d.verdict, fit.params, truth.bandwidth_hz
    );
    assert_eq!(d.verdict.name(), "current_loop");
    let f3 = fit
        .params
        .iter()
        .find(|p| p.name == "bandwidth_3db_hz")
        .expect("the bandwidth")
        .value;
    assert!(
        (f3 / truth.bandwidth_hz - 1.0).abs() < 0.01,
        "{f3} vs {}",
        truth.bandwidth_hz
    );
}

//! Plant files and specs: parsing, validation (errors, not panics), the example files, the
//! file simulation path, and speed.

use super::*;
use std::path::Path;

fn plants_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../plants")
}

#[test]
fn plant_files_without_effects_parse_as_before() {
    let p = PlantFile::parse(DEFAULT_PLANT, "embedded default plant").unwrap();
    assert!(!p.has_effects());
    assert_eq!(p.effects, Effects::default());
    assert_eq!(p.chain.masses(), 3);
    assert_eq!(p.spec().effects.encoder_counts_per_rev, Some(1_048_576));
}

#[test]
fn example_plant_files_parse_and_simulate() {
    let mut seen = 0;
    for entry in std::fs::read_dir(plants_dir()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let p = std::fs::read_to_string(&path)
            .map_err(|e| e.to_string())
            .and_then(|t| {
                PlantFile::parse(&t, &path.display().to_string()).map_err(|e| e.to_string())
            })
            .unwrap_or_else(|e| panic!("{e}"));
        if p.has_effects() {
            seen += 1;
            let torque = multisine(400, &[1, 5, 20, 60], 2);
            let pos = simulate_file_positions(&p, &torque, 1).unwrap();
            assert_eq!(pos.len(), torque.len());
            assert!(pos.iter().all(|x| x.is_finite()), "{}", path.display());
        }
    }
    assert!(seen >= 2, "{seen} example files with effects");
}

#[test]
fn effects_sections_parse_with_defaults() {
    let text = r#"
[chain]
inertia_kgm2 = [2e-3, 6e-3]
stiffness_nm_per_rad = [8000.0]
damping_nms_per_rad = [0.5]

[effects]
torque_noise_nm = 0.01
encoder_counts_per_rev = 65536

[effects.current_loop]
bandwidth_hz = 800.0

[effects.friction]
coulomb_nm = 0.05

[effects.backlash]
coupling = 0
half_gap_rad = 1e-4

[effects.hardening_stiffness]
coupling = 1
x_ref_rad = 0.01

[effects.time_delay]
delay_s = 1.3e-4

[effects.gravity]
m_g_l_nm = 0.3

[effects.extra_mode]
inertia_kgm2 = 1e-3
stiffness_nm_per_rad = 3e4
"#;
    let s = PlantSpec::from_toml(text).unwrap();
    let e = &s.effects;
    assert!(e.any());
    let cl = e.current_loop.as_ref().unwrap();
    assert_eq!(
        (cl.order, cl.damping_ratio),
        (1, std::f64::consts::FRAC_1_SQRT_2)
    );
    assert_eq!(e.friction.as_ref().unwrap().viscous_nms_per_rad, 0.0);
    assert_eq!(e.gravity.as_ref().unwrap().offset_rad, 0.0);
    assert_eq!(e.extra_mode.as_ref().unwrap().damping_nms_per_rad, 0.0);
    // coupling 1 exists only thanks to the extra mode
    assert_eq!(s.extended_chain().masses(), 3);
    let mut sim = PlantSim::new(&s, 4000.0, 10, 3).unwrap();
    for k in 0..4000 {
        sim.step(0.2 * (k as f64 * 0.01).sin());
    }
    assert!(sim.sample().position_rad.is_finite());
    // a typo is an error, not silently ignored
    let bad = text.replace("coulomb_nm", "coulomb");
    assert!(matches!(
        PlantSpec::from_toml(&bad),
        Err(PlantError::Parse(_))
    ));
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let base = PlantSpec::linear(chain2());
    let err = |f: &dyn Fn(&mut PlantSpec)| {
        let mut s = base.clone();
        f(&mut s);
        PlantSim::new(&s, 2000.0, 10, 1).unwrap_err()
    };
    assert!(matches!(
        err(&|s| s.effects.backlash = Some(Backlash {
            coupling: 1,
            half_gap_rad: 1e-3
        })),
        PlantError::Coupling {
            index: 1,
            couplings: 1,
            ..
        }
    ));
    assert!(matches!(
        err(&|s| s.effects.hardening_stiffness = Some(Hardening {
            coupling: 0,
            x_ref_rad: 0.0
        })),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        err(&|s| s.effects.current_loop = Some(CurrentLoop {
            bandwidth_hz: -1.0,
            order: 1,
            damping_ratio: 0.7
        })),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        err(&|s| s.effects.current_loop = Some(CurrentLoop {
            bandwidth_hz: 100.0,
            order: 3,
            damping_ratio: 0.7
        })),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        err(&|s| s.effects.friction = Some(Friction {
            coulomb_nm: f64::NAN,
            viscous_nms_per_rad: 0.0
        })),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        err(&|s| s.effects.time_delay = Some(TimeDelay { delay_s: -1e-3 })),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        err(&|s| s.effects.time_delay = Some(TimeDelay { delay_s: 1e300 })),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        err(&|s| s.effects.encoder_counts_per_rev = Some(0)),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        err(&|s| s.chain.inertia_kgm2[1] = -1.0),
        PlantError::Chain(_)
    ));
    assert!(matches!(
        err(&|s| s.effects.extra_mode = Some(ExtraMode {
            inertia_kgm2: 1e-3,
            stiffness_nm_per_rad: f64::INFINITY,
            damping_nms_per_rad: 0.0
        })),
        PlantError::Parameter { .. }
    ));
    assert!(matches!(
        PlantSim::new(&base, 0.0, 10, 1),
        Err(PlantError::CycleRate { .. })
    ));
    assert!(matches!(
        PlantSim::new(&base, f64::NAN, 10, 1),
        Err(PlantError::CycleRate { .. })
    ));
    assert!(matches!(
        PlantSim::new(&base, 2000.0, 0, 1),
        Err(PlantError::Substeps)
    ));
    // 367 Hz mode at 200 Hz cycle and 1 substep: |lambda| h = 11.5
    assert!(matches!(
        PlantSim::new(&base, 200.0, 1, 1),
        Err(PlantError::Unstable { .. })
    ));
    assert!(PlantSim::new(&base, 200.0, 10, 1).is_ok());
    assert!(PlantFile::parse("[chain]\ninertia_kgm2 = [1e-3]\nstiffness_nm_per_rad = []\ndamping_nms_per_rad = []\n[effects.backlash]\ncoupling = 0\nhalf_gap_rad = 1e-3\n", "x.toml").unwrap_err().to_string().starts_with("x.toml: "));
    // a non-finite command does not panic
    let mut sim = PlantSim::new(&base, 2000.0, 10, 1).unwrap();
    sim.step(f64::NAN);
    assert!(sim.sample().position_rad.is_nan());
}

/// A plant file whose only effect is the encoder goes through PlantSim and agrees with the
/// exact path within a count.
#[test]
fn file_path_with_effects_agrees_with_the_exact_path() {
    let text = format!(
        "{}\n[effects]\nencoder_counts_per_rev = 1048576\n",
        DEFAULT_PLANT.replace("velocity_noise_rel = 0.01", "velocity_noise_rel = 0.0")
    );
    let p = PlantFile::parse(&text, "t").unwrap();
    assert!(p.has_effects());
    let torque = multisine(2000, &[1, 4, 30, 200, 500], 2);
    let got = simulate_file_positions(&p, &torque, 1).unwrap();
    let want = crate::sim::simulate_position(&p.chain, &torque, &p.sim_options(1)).unwrap();
    let q = 2.0 * PI / 1_048_576.0;
    let worst = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst <= q * 1.000001, "worst {worst:e}, count {q:e}");
}

/// Real-time margin: the SCARA shoulder with every effect at 4 kHz and 10 sub-steps.
#[test]
fn plant_sim_is_fast() {
    let text = std::fs::read_to_string(plants_dir().join("scara_all_effects.toml")).unwrap();
    let p = PlantFile::parse(&text, "scara_all_effects.toml").unwrap();
    let mut sim = PlantSim::new(&p.spec(), 4000.0, 10, 1).unwrap();
    let cycles = 400_000; // 100 s of drive time
    let t0 = std::time::Instant::now();
    let mut acc = 0.0;
    for k in 0..cycles {
        acc += sim.sample().position_rad;
        sim.step(0.3 * (k as f64 * 2e-3).sin());
    }
    let dt = t0.elapsed().as_secs_f64();
    let rate = cycles as f64 / dt;
    eprintln!(
        "PlantSim: {rate:.3e} cycles/s ({:.3e} sub-steps/s), {:.0}x real time at 4 kHz",
        rate * 10.0,
        rate / 4000.0
    );
    assert!(acc.is_finite());
    assert!(rate > 40_000.0, "{rate} cycles/s");
}

#[test]
fn plant_sim_can_move_to_the_drive_thread() {
    fn send<T: Send + 'static>() {}
    send::<PlantSim>();
    send::<AxisSample>();
}

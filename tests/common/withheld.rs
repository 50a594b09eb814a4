//! The withheld-effect benchmark's case generator: a random 3-mass axis (the SCARA shoulder
//! of the demo with an 30x stiffer arm spring, arm mode ~16/27 Hz, every parameter scaled by
//! up to +-20 %) with exactly one unmodelled effect of
//! random size, measured with an odd random-phase multisine at two amplitudes by the
//! fine-step RK4 plant simulator `flexid::plant::PlantSim` (20 sub-steps per sample; not the
//! diagnosis's own simulation). The recordings are written to a directory; the effect is
//! written only to `truth.json`, which the diagnosis never reads.

#![allow(dead_code)]

use flexid::excitation::{AmplitudeShape, MultisineDesign, PhaseDesign};
use flexid::model::Chain;
use flexid::plant::{
    run, Backlash, CurrentLoop, Effects, ExtraMode, Friction, Gravity, Hardening, PlantSim,
    PlantSpec, TimeDelay,
};
use flexid::recording::{write_recording, Recording, Sidecar};
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};

pub const CLASSES: [&str; 8] = [
    "none",
    "coulomb_friction",
    "backlash",
    "hardening_stiffness",
    "time_delay",
    "current_loop",
    "unmodelled_mode",
    "gravity",
];

pub const FS: f64 = 2000.0;
pub const PERIOD: usize = 4000;
pub const LEVELS_NM: [f64; 2] = [0.05, 0.2];

pub struct Case {
    pub recordings: Vec<PathBuf>,
    pub truth_path: PathBuf,
}

fn chain(rng: &mut impl Rng) -> Chain {
    let mut s = || (rng.random_range(-0.2..0.2f64)).exp();
    Chain::new(
        vec![3.614e-3 * s(), 5.098e-3 * s(), 17.188e-3 * s()],
        vec![2.906e4 * s(), 171.0 * s()],
        vec![0.47 * s(), 0.018 * s()],
    )
    .unwrap()
}

/// RMS deflection of each coupling of `chain` under torque `u` (exact ZOH state space).
fn deflection_rms(chain: &Chain, u: &[f64]) -> Vec<f64> {
    let spec = PlantSpec::linear(chain.clone());
    let mut sim = PlantSim::new(&spec, FS, 4, 0).unwrap();
    let n = chain.masses();
    let mut s = vec![0.0; n - 1];
    for &t in u {
        sim.step(t);
        let p = sim.body_positions();
        for k in 0..n - 1 {
            s[k] += (p[k + 1] - p[k]).powi(2);
        }
    }
    s.iter().map(|v| (v / u.len() as f64).sqrt()).collect()
}

fn excitation(seed: u64, rms: f64) -> (Vec<f64>, flexid::excitation::ExcitationInfo) {
    let mut d = MultisineDesign::new(FS, PERIOD, [0.5, 800.0], 100.0, rms);
    d.phases = PhaseDesign::OddRandom { seed, group: 3 };
    d.amplitude = AmplitudeShape::Flat;
    d.crest_iterations = 10;
    let m = d.generate().unwrap();
    (m.repeat(7), m.info(5, 2))
}

/// How the nominal plant varies from the benchmark's original one (all off: the original).
#[derive(Debug, Clone, Copy, Default)]
pub struct Variation {
    /// Viscous friction from the motor to the ground in every plant (corner `b / J_total`
    /// of 0.3-3 Hz), which the nominal model must carry without naming an effect.
    pub viscous: bool,
}

/// Generate one case of `class` into `dir` (created). Returns the recordings and the truth.
pub fn generate(class: &str, seed: u64, dir: &Path) -> Case {
    generate_with(class, seed, dir, Variation::default())
}

/// [`generate`] on a varied nominal plant.
pub fn generate_with(class: &str, seed: u64, dir: &Path, var: Variation) -> Case {
    std::fs::create_dir_all(dir).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x5eed_d1a9);
    let ch = chain(&mut rng);
    // drawn from its own stream so that the original cases stay the same
    let nominal_b = {
        let mut r = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0b5c_0005);
        ch.total_inertia() * 2.0 * std::f64::consts::PI * r.random_range(0.3..3.0)
    };
    let exc: Vec<_> = LEVELS_NM
        .iter()
        .map(|&l| excitation(seed.wrapping_mul(31) + 7, l))
        .collect();
    let mut e = Effects {
        torque_noise_nm: 2e-4,
        encoder_counts_per_rev: Some(1 << 22),
        ..Effects::default()
    };
    let jt = ch.total_inertia();
    let mut truth = serde_json::json!({"effect": class, "seed": seed});
    match class {
        "none" => {}
        "coulomb_friction" => {
            let tc = LEVELS_NM[0] * rng.random_range(0.05..0.3);
            let b = jt * 2.0 * std::f64::consts::PI * rng.random_range(0.0..0.3);
            e.friction = Some(Friction {
                coulomb_nm: tc,
                viscous_nms_per_rad: b,
            });
            truth["coulomb_nm"] = tc.into();
            truth["viscous_nms_per_rad"] = b.into();
        }
        "backlash" => {
            // in the gear
            let k = 0;
            let x = deflection_rms(&ch, &exc[0].0)[k];
            let g = x * rng.random_range(0.5..2.0);
            e.backlash = Some(Backlash {
                coupling: k,
                half_gap_rad: g,
            });
            truth["coupling"] = k.into();
            truth["half_gap_rad"] = g.into();
        }
        "hardening_stiffness" => {
            let k = rng.random_range(0..2usize);
            let x = deflection_rms(&ch, &exc[1].0)[k];
            let xr = x * rng.random_range(1.5..5.0);
            e.hardening_stiffness = Some(Hardening {
                coupling: k,
                x_ref_rad: xr,
            });
            truth["coupling"] = k.into();
            truth["x_ref_rad"] = xr.into();
        }
        "time_delay" => {
            let d = rng.random_range(0.2..2.0) / FS;
            e.time_delay = Some(TimeDelay { delay_s: d });
            truth["delay_s"] = d.into();
        }
        "current_loop" => {
            let order = rng.random_range(1..=2u8);
            let bw = rng.random_range(300.0..1500.0);
            let z = rng.random_range(0.5..0.9);
            e.current_loop = Some(CurrentLoop {
                bandwidth_hz: bw,
                order,
                damping_ratio: z,
            });
            truth["order"] = order.into();
            truth["bandwidth_hz"] = bw.into();
            truth["damping_ratio"] = z.into();
        }
        "unmodelled_mode" => {
            let jl = ch.inertia_kgm2[2];
            // below the arm's anti-resonance: a mode beyond the soft arm spring above it
            // is invisible from the motor
            let je = jl * rng.random_range(0.3..1.0);
            let f = ch.antiresonances_hz()[0] * rng.random_range(0.35..0.7);
            let c = je * (2.0 * std::f64::consts::PI * f).powi(2);
            let d = 2.0 * 0.02 * (c * je).sqrt();
            e.extra_mode = Some(ExtraMode {
                inertia_kgm2: je,
                stiffness_nm_per_rad: c,
                damping_nms_per_rad: d,
            });
            truth["inertia_kgm2"] = je.into();
            truth["stiffness_nm_per_rad"] = c.into();
        }
        "gravity" => {
            let mgl = rng.random_range(1.0..5.0);
            e.gravity = Some(Gravity {
                m_g_l_nm: mgl,
                offset_rad: 0.0,
            });
            // the swinging mode gravity creates is undamped in a free chain and would never
            // settle: the axis's bearings damp it (zeta 5-20 %)
            let b = 2.0 * rng.random_range(0.05..0.2) * (mgl * jt).sqrt();
            e.friction = Some(Friction {
                coulomb_nm: 0.0,
                viscous_nms_per_rad: b,
            });
            truth["m_g_l_nm"] = mgl.into();
            truth["bearing_damping_nms_per_rad"] = b.into();
        }
        other => panic!("unknown class {other}"),
    }
    if var.viscous {
        let f = e.friction.get_or_insert(Friction {
            coulomb_nm: 0.0,
            viscous_nms_per_rad: 0.0,
        });
        f.viscous_nms_per_rad += nominal_b;
        truth["nominal_viscous_nms_per_rad"] = nominal_b.into();
    }
    let spec = PlantSpec {
        chain: ch.clone(),
        effects: e,
    };
    let mut recordings = Vec::new();
    for (i, (u, info)) in exc.iter().enumerate() {
        let mut sim = PlantSim::new(&spec, FS, 20, seed * 10 + i as u64).unwrap();
        let pos: Vec<f64> = run(&mut sim, u).map(|s| s.position_rad).collect();
        let rec = Recording {
            time_s: (0..u.len()).map(|k| k as f64 / FS).collect(),
            torque_cmd_nm: u.clone(),
            position_rad: Some(pos),
            velocity_rad_s: None,
            acceleration_rad_s2: None,
            torque_actual_nm: None,
            sample_rate_hz: FS,
            sidecar: Sidecar {
                sample_rate_hz: Some(FS),
                excitation: Some(info.clone()),
                ..Sidecar::default()
            },
        };
        let p = dir.join(format!("level{i}.csv"));
        write_recording(&p, &rec).unwrap();
        recordings.push(p);
    }
    truth["chain"] = serde_json::to_value(&ch).unwrap();
    let truth_path = dir.join("truth.json");
    std::fs::write(&truth_path, serde_json::to_string_pretty(&truth).unwrap()).unwrap();
    Case {
        recordings,
        truth_path,
    }
}

/// Reads the case's recordings back and runs the diagnosis on them alone, as a 3-mass
/// axis (the truth file is not read).
pub fn diagnose_case(case: &Case) -> flexid::diagnose::Diagnosis {
    let recs: Vec<Recording> = case
        .recordings
        .iter()
        .map(|p| flexid::recording::read_recording(p).unwrap())
        .collect();
    flexid::diagnose::diagnose(
        &recs,
        &flexid::diagnose::DiagnoseOptions {
            masses: 3,
            ..flexid::diagnose::DiagnoseOptions::default()
        },
    )
    .unwrap()
}

//! Speed of identification on long recordings (issue 14, "Speed"): a recording of 10^6
//! samples of a 3-mass chain, once periodic (125 periods of a multisine) and once white
//! noise (Welch), identified with the automatic order on one worker thread
//! (`FitOptions::threads = 1`). Target: under 0.5 s each. Prints the median of the runs
//! and each step's share; reported, not asserted (shared machines are noisy).
//!
//! `cargo bench --bench identify_speed -- [RUNS]` (default 5).

use flexid::analysis::{analyze, AnalysisOptions};
use flexid::excitation::{AmplitudeShape, MultisineDesign, PhaseDesign};
use flexid::identify::fit::FitOptions;
use flexid::model::Chain;
use flexid::plant::{run, Effects, PlantSim, PlantSpec};
use flexid::recording::Recording;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::time::Instant;

#[path = "../tests/unseen/mod.rs"]
mod unseen;

const SAMPLES: usize = 1_000_000;
const FS: f64 = 4000.0;

fn chain() -> Chain {
    // motor, gear, arm: pairs near 40/60 and 180/260 Hz, 2 % damping
    Chain::new(
        vec![1.0e-3, 1.0e-3, 3.0e-3],
        vec![400.0, 1200.0],
        vec![0.01, 0.02],
    )
    .expect("a valid chain")
}

fn record(periodic: bool) -> Recording {
    let chain = chain();
    let rms = 0.3;
    let (torque, info) = if periodic {
        let period = 8000; // 0.5 Hz lines
        let mut d = MultisineDesign::new(FS, period, [0.5, 0.4 * FS], 3.0, rms);
        d.phases = PhaseDesign::Random { seed: 7 };
        d.amplitude = AmplitudeShape::Flat;
        d.crest_iterations = 5;
        let m = d.generate().expect("a multisine");
        let periods = SAMPLES / period;
        (m.repeat(periods), Some(m.info(periods - 1, 1)))
    } else {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let w = Normal::new(0.0, rms).unwrap();
        ((0..SAMPLES).map(|_| w.sample(&mut rng)).collect(), None)
    };
    let spec = PlantSpec {
        chain,
        effects: Effects {
            torque_noise_nm: 1e-3,
            encoder_counts_per_rev: Some(1 << 20),
            ..Effects::default()
        },
    };
    let mut sim = PlantSim::new(&spec, FS, 4, 7).expect("a stable plant");
    let pos: Vec<f64> = run(&mut sim, &torque).map(|s| s.position_rad).collect();
    unseen::position_recording(FS, torque, pos, info)
}

fn main() {
    let runs: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(5);
    let opts = AnalysisOptions {
        fit: FitOptions {
            threads: 1,
            ..FitOptions::default()
        },
        ..AnalysisOptions::default()
    };
    for periodic in [true, false] {
        let rec = record(periodic);
        let mut times = Vec::new();
        let mut masses = 0;
        let mut found = String::new();
        for _ in 0..runs {
            let t = Instant::now();
            let a = analyze(&rec, &opts).expect("an analysis");
            times.push(t.elapsed().as_secs_f64());
            if std::env::var("VERBOSE").is_ok() {
                for o in &a.orders {
                    println!(
                        "  order {} cost {:.4e} chi2/dof {:.3} {:?}",
                        o.masses, o.cost, o.chi2_per_dof, o.error
                    );
                }
                for p in a.detection.pairs.iter().chain(&a.detection.unconfirmed) {
                    println!(
                        "  pair {:.2}/{:.2} depth {:.1} height {:.1} rise {:.0}",
                        p.ar_hz, p.r_hz, p.depth_db, p.height_db, p.phase_rise_deg
                    );
                }
                println!(
                    "  lines {} method {:?} notes {:?}",
                    a.measured.frf.len(),
                    a.measured.method,
                    a.notes
                );
            }
            masses = a.model.as_ref().map_or(0, |m| m.masses);
            found = a.model.as_ref().map_or(String::new(), |m| {
                format!("AR {:.1?} R {:.1?} Hz", m.antiresonance_hz, m.resonance_hz)
            });
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{} samples, {}: identified {} bodies ({found}; true AR {:.1?} R {:.1?} Hz); median {:.3} s over {} runs (min {:.3}, max {:.3}); target < 0.5 s",
            rec.torque_cmd_nm.len(),
            if periodic { "periodic multisine" } else { "white noise (Welch)" },
            masses,
            chain().antiresonances_hz(),
            chain().resonances_hz(),
            times[times.len() / 2],
            runs,
            times[0],
            times[times.len() - 1]
        );
    }
}

//! The benchmark's cases: groups, classes, seeds, and what a case's `truth.json` holds
//! ([`super::generate`] makes a case from its seed alone).
//!

use super::causes::CAUSES;
use super::effects::EFFECTS;
use super::excitation::Design;
use super::plant::{Output, Plant};
use flexid::model::Chain;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The benchmark's groups.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Group {
    /// Single library effects at full size, and `none`.
    A,
    /// Single library effects at a third of the size.
    B,
    /// Pairs of library effects, each at full size.
    C,
    /// Causes outside the library.
    D,
    /// Nominal variations with no effect.
    E,
}

pub const GROUPS: [Group; 5] = [Group::A, Group::B, Group::C, Group::D, Group::E];

/// The pairs of group C.
pub const PAIRS: [&str; 6] = [
    "coulomb_friction+unmodelled_mode",
    "backlash+time_delay",
    "hardening_stiffness+current_loop",
    "gravity+time_delay",
    "unmodelled_mode+current_loop",
    "coulomb_friction+hardening_stiffness",
];

/// The nominal variations of group E (the named one forced, the rest drawn).
pub const VARIATIONS: [&str; 10] = [
    "four_masses",
    "fs_4khz",
    "schroeder",
    "random_phase",
    "swept_sine",
    "stepped_sine",
    "no_viscous",
    "noise_x3",
    "velocity_output",
    "encoder_14bit",
];

impl Group {
    pub fn name(self) -> &'static str {
        match self {
            Group::A => "A",
            Group::B => "B",
            Group::C => "C",
            Group::D => "D",
            Group::E => "E",
        }
    }

    pub fn parse(s: &str) -> Option<Group> {
        GROUPS
            .into_iter()
            .find(|g| g.name().eq_ignore_ascii_case(s))
    }

    pub fn index(self) -> usize {
        GROUPS.iter().position(|g| *g == self).unwrap()
    }

    /// What the group holds.
    pub fn describe(self) -> &'static str {
        match self {
            Group::A => "single effects at full size, and none",
            Group::B => "single effects at a third of the size",
            Group::C => "pairs of effects, both named",
            Group::D => "causes outside the library: unexplained, band overlapping",
            Group::E => "nominal variations with no effect: none",
        }
    }

    /// The Done-when share of right answers.
    pub fn target(self) -> f64 {
        match self {
            Group::A => 0.95,
            Group::B => 0.85,
            Group::C | Group::D => 0.80,
            Group::E => 0.90,
        }
    }

    /// The classes (rows) of the group.
    pub fn classes(self) -> Vec<&'static str> {
        match self {
            Group::A => std::iter::once("none").chain(EFFECTS).collect(),
            Group::B => EFFECTS.to_vec(),
            Group::C => PAIRS.to_vec(),
            Group::D => CAUSES.to_vec(),
            Group::E => VARIATIONS.to_vec(),
        }
    }
}

/// Case `k` of class index `class` in `group` from seed base `base` (k < 100).
pub fn seed_of(base: u64, group: Group, class: usize, k: usize) -> u64 {
    assert!(k < 100, "at most 100 cases per class");
    base + 10_000 * group.index() as u64 + 100 * class as u64 + k as u64
}

/// One case to generate.
#[derive(Debug, Clone)]
pub struct Spec {
    pub group: Group,
    pub class: &'static str,
    pub seed: u64,
    /// A sample rate other than the drawn one (the test's 1 and 8 kHz).
    pub fs_hz: Option<f64>,
}

/// One effect's or cause's size in a case.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sizing {
    pub class: String,
    /// The diagnosis's right name for it (`unexplained` for a cause).
    pub answer: String,
    pub size_name: String,
    /// The typical size drawn and its visibility beyond the nominal model (alone on the
    /// nominal axis).
    pub typical_size: f64,
    pub typical_visibility: f64,
    /// The full size: the typical one, enlarged until `target_visibility` where it fell
    /// short; and its visibility.
    pub full_size: f64,
    pub full_visibility: f64,
    pub target_visibility: f64,
    /// The size applied in this case (full, or a third in group B), its visibility beyond
    /// the nominal model and against the true nominal chain.
    pub size: f64,
    pub visibility: f64,
    pub visibility_true_chain: f64,
    /// The visibility beyond the nominal model against the scatter the case's own
    /// recordings show (periodic multisines only).
    #[serde(default)]
    pub visibility_measured: Option<f64>,
    /// Everything drawn but the size.
    pub shape: serde_json::Value,
}

/// The measurement of a case.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Measurement {
    pub fs_hz: f64,
    pub excitation: Design,
    pub levels_rms_nm: Vec<f64>,
    pub encoder_bits: u32,
    pub torque_noise_nm: f64,
    pub noise_factor: f64,
    pub output: Output,
    pub substeps: usize,
    pub samples_per_level: usize,
}

/// Everything about a case, written to `truth.json` (the diagnosis never reads it).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Truth {
    pub group: Group,
    pub class: String,
    pub seed: u64,
    /// The nominal chain's bodies (the diagnosis's `--masses`).
    pub masses: usize,
    /// The right answers: the library effects present (A, B, C), or empty.
    pub effects: Vec<String>,
    /// The right verdict where one is required (A, B, D, E: `none`, an effect,
    /// `unexplained`); None for pairs (both must be among the effects named).
    pub verdict: Option<String>,
    /// A library effect (A, B) whose response had no steady state at any size tried (a
    /// load on a cubic spring to the ground under a stepped sine: after each step the load
    /// swings slowly about the ground on the spring, period after period differently): the
    /// records hold no periodic FRF, and `unexplained` (the gap is real, no model of a
    /// steady state explains it) is right beside the effect's name.
    #[serde(default)]
    pub no_steady_state: bool,
    /// Where a cause outside the library acts on the FRF [Hz] (group D).
    pub band_hz: Option<[f64; 2]>,
    pub sizes: Vec<Sizing>,
    /// Visibility of everything added together, beyond the nominal model
    /// ([`super::visibility::Projector`]) and against the true nominal chain.
    pub visibility: f64,
    pub visibility_true_chain: f64,
    pub measurement: Measurement,
    pub nominal_chain: Chain,
    pub nominal_motor_viscous_nms_per_rad: f64,
    pub plant: Plant,
}

/// A generated case on disk.
pub struct Case {
    pub recordings: Vec<PathBuf>,
    pub truth_path: PathBuf,
    pub truth: Truth,
}

/// Read a case's truth back.
pub fn read_truth(path: &Path) -> Truth {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

//! What the world's axis is made of: bodies and couplings, what acts between the motor (or
//! a body) and the ground, the drive's torque path and the sensor's measurement path. Plain
//! data, serialised whole into each case's `truth.json`; [`super::simulator`] integrates it
//! and [`super::analytic`] gives its small-signal frequency response.
//!
//! Units are in every field name. Body 0 is the motor; body `k` and `k + 1` are joined by
//! coupling `k`, whose deflection is `q[k + 1] - q[k]`.

use flexid::model::Chain;
use serde::{Deserialize, Serialize};

/// The law of a coupling's spring.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "snake_case")]
pub enum Law {
    /// A linear spring and damper.
    Linear,
    /// Backlash: play of `2 half_gap_rad` in the coupling (a gear's flanks). Inside the
    /// gap nothing is transmitted; in contact the spring acts on the deflection beyond the
    /// flank, `c (x - g sign x)`, and the contact damping `d v` grows from zero over the
    /// first `contact_ramp_rad` of penetration (the flanks' oil film is squeezed out), so
    /// the torque never jumps at an impact.
    DeadZone {
        half_gap_rad: f64,
        contact_ramp_rad: f64,
    },
    /// A spring that stiffens with deflection, `c x (1 + (x / x_ref)^2)` (a harmonic
    /// drive's flexspline, a preloaded bearing).
    Hardening { x_ref_rad: f64 },
}

/// A coupling between two neighbouring bodies.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Coupling {
    pub stiffness_nm_per_rad: f64,
    pub damping_nms_per_rad: f64,
    pub law: Law,
}

/// Dry friction on the motor: a Stribeck curve, `(Tc + (Ts - Tc) exp(-(v/vs)^2))`, made
/// smooth through zero speed by `tanh(v / v_reg)` (the pre-sliding micro-slip of a real
/// contact; not the stick/slip switching of the diagnosis's own model).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Friction {
    pub coulomb_nm: f64,
    pub static_nm: f64,
    pub stribeck_rad_s: f64,
    pub regularisation_rad_s: f64,
}

/// An arm swinging under gravity about a horizontal axis: `-m g l sin(q)` on `body` (the
/// arm hanging at `q = 0`), with the damping of its bearing to the ground.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Gravity {
    pub body: usize,
    pub m_g_l_nm: f64,
    pub bearing_damping_nms_per_rad: f64,
}

/// A purely cubic spring from `body` to the ground, `-k3 q^3` (a cable loop or a
/// counterbalance spring that stiffens with travel; the Silverbox's Duffing spring).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GroundCubic {
    pub body: usize,
    pub cubic_nm_per_rad3: f64,
}

/// Cogging torque of a permanent-magnet motor: `-A sin(N q)` on the motor, `N` detent
/// periods per revolution (magnets and slots), the axis resting in a detent at `q = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Cogging {
    pub amplitude_nm: f64,
    pub periods_per_rev: f64,
}

/// A low-pass of order 1 (`w / (s + w)`) or 2 (`w^2 / (s^2 + 2 z w s + w^2)`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LowPass {
    pub order: u8,
    pub bandwidth_hz: f64,
    pub damping_ratio: f64,
}

/// A notch (band-stop) filter `(s^2 + 2 zz w s + w^2) / (s^2 + 2 zp w s + w^2)`: depth
/// `zz / zp` at the centre, width set by `zp`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Notch {
    pub centre_hz: f64,
    pub pole_damping_ratio: f64,
    pub zero_damping_ratio: f64,
}

/// A base-excited resonator: the encoder's disc on a compliant shaft following the motor,
/// `(2 z w s + w^2) / (s^2 + 2 z w s + w^2)` from motor angle to disc angle.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Resonator {
    pub frequency_hz: f64,
    pub damping_ratio: f64,
}

/// The drive between the torque command and the motor's torque: a delay (communication
/// and computation, any fraction of a sample), a notch filter on the torque reference, the
/// current loop, and the power stage's dead zone (`sign(T) max(|T| - d, 0)`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Drive {
    pub delay_s: f64,
    pub notch: Option<Notch>,
    pub current_loop: Option<LowPass>,
    pub dead_zone_nm: f64,
}

/// Which motion signal the recording holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Output {
    /// The encoder's position (quantised), the usual case.
    #[default]
    Position,
    /// The drive's velocity estimate: the motor's velocity at the sample instant (an
    /// observer on a sin/cos encoder), with white noise as large as the differenced
    /// quantisation of the same encoder.
    Velocity,
}

/// The measurement: encoder resolution, what lies between the motor and the encoder's
/// reading, which signal is recorded, and the noise of the drive's current reading
/// (`torque_actual_nm`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sensor {
    pub encoder_bits: u32,
    /// The encoder's disc on a compliant shaft.
    pub shaft: Option<Resonator>,
    /// A low-pass on the measured position only (the drive's encoder/velocity filter);
    /// the torque path and `torque_actual_nm` do not see it.
    pub lowpass: Option<LowPass>,
    /// Play between the encoder's disc and its shaft (half of it; 0: none): the disc,
    /// held by its bearing's friction, moves only when the shaft pushes it against one
    /// side, so the reading lags by up to this much after every reversal.
    pub half_play_rad: f64,
    pub output: Output,
    pub current_noise_nm: f64,
}

impl Sensor {
    /// One encoder count [rad].
    pub fn count_rad(&self) -> f64 {
        2.0 * std::f64::consts::PI / (1u64 << self.encoder_bits) as f64
    }
}

/// The whole axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plant {
    /// Bodies, motor first [kg m^2]; an unmodelled body is appended at the load end.
    pub inertia_kgm2: Vec<f64>,
    /// `couplings[k]` joins bodies `k` and `k + 1`.
    pub couplings: Vec<Coupling>,
    /// Viscous friction from the motor to the ground (bearings, seals), may be zero.
    pub motor_viscous_nms_per_rad: f64,
    pub friction: Option<Friction>,
    pub gravity: Option<Gravity>,
    pub ground_cubic: Option<GroundCubic>,
    pub cogging: Option<Cogging>,
    pub drive: Drive,
    pub sensor: Sensor,
    /// Standard deviation of the white disturbance torque on the motor, held over each
    /// sample [N m].
    pub torque_noise_nm: f64,
}

impl Plant {
    /// The linear chain `chain` with viscous friction to the ground, an encoder of
    /// `encoder_bits` and nothing else.
    pub fn nominal(chain: &Chain, motor_viscous_nms_per_rad: f64, encoder_bits: u32) -> Plant {
        Plant {
            inertia_kgm2: chain.inertia_kgm2.clone(),
            couplings: chain
                .stiffness_nm_per_rad
                .iter()
                .zip(&chain.damping_nms_per_rad)
                .map(|(&c, &d)| Coupling {
                    stiffness_nm_per_rad: c,
                    damping_nms_per_rad: d,
                    law: Law::Linear,
                })
                .collect(),
            motor_viscous_nms_per_rad,
            friction: None,
            gravity: None,
            ground_cubic: None,
            cogging: None,
            drive: Drive::default(),
            sensor: Sensor {
                encoder_bits,
                shaft: None,
                lowpass: None,
                half_play_rad: 0.0,
                output: Output::Position,
                current_noise_nm: 0.0,
            },
            torque_noise_nm: 0.0,
        }
    }

    pub fn bodies(&self) -> usize {
        self.inertia_kgm2.len()
    }

    pub fn total_inertia_kgm2(&self) -> f64 {
        self.inertia_kgm2.iter().sum()
    }

    /// The bodies and couplings as a linear chain (laws linearised in contact).
    pub fn chain(&self) -> Chain {
        Chain::new(
            self.inertia_kgm2.clone(),
            self.couplings
                .iter()
                .map(|c| c.stiffness_nm_per_rad)
                .collect(),
            self.couplings
                .iter()
                .map(|c| c.damping_nms_per_rad)
                .collect(),
        )
        .expect("a valid chain")
    }
}

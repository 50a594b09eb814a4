//! The plant specification: a chain plus optional unmodelled effects (`[effects]`).

use super::PlantError;
use crate::model::Chain;
use serde::{Deserialize, Serialize};

/// A simulated servo axis: the compliant chain and the effects the identification does not
/// model. All effects are off by default; with none, [`super::PlantSim`] is the chain under
/// zero-order hold, like [`crate::sim::simulate_position`].
///
/// TOML form (the `[effects]` scalar keys must come before its sub-tables):
///
/// ```toml
/// [chain]
/// inertia_kgm2 = [3.614e-3, 5.098e-3, 17.188e-3]
/// stiffness_nm_per_rad = [2.906e4, 5.706]
/// damping_nms_per_rad = [0.47, 0.018]
///
/// [effects]
/// torque_noise_nm = 0.002
/// encoder_counts_per_rev = 1048576
///
/// [effects.friction]
/// coulomb_nm = 0.05
/// viscous_nms_per_rad = 1e-3
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSpec {
    /// The linear chain (body 1 = motor).
    pub chain: Chain,
    /// The unmodelled effects, each optional.
    #[serde(default)]
    pub effects: Effects,
}

/// The unmodelled effects of a plant, each `None` (off) unless given.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Effects {
    /// RMS [N m] of a white disturbance torque on the motor, one normal draw per cycle held
    /// over the cycle (as [`crate::sim::SimOptions::torque_noise_nm`]). 0 = off.
    pub torque_noise_nm: f64,
    /// Encoder resolution [counts/rev] of the sampled motor position; `None` = ideal.
    pub encoder_counts_per_rev: Option<u64>,
    /// Current (torque) loop between the command and the motor torque.
    pub current_loop: Option<CurrentLoop>,
    /// Friction on the motor (Coulomb with stiction, plus viscous).
    pub friction: Option<Friction>,
    /// A dead zone (gear backlash) in one spring.
    pub backlash: Option<Backlash>,
    /// A hardening (cubic) spring.
    pub hardening_stiffness: Option<Hardening>,
    /// A pure delay between the command and the current loop.
    pub time_delay: Option<TimeDelay>,
    /// Gravity on the last body (a pendulum-like restoring torque).
    pub gravity: Option<Gravity>,
    /// One more body and spring appended after the last body of the chain.
    pub extra_mode: Option<ExtraMode>,
}

/// Current loop: the motor torque follows the (delayed) command through
/// `1/(1 + s/wc)` (order 1) or `wc^2/(s^2 + 2 zeta wc s + wc^2)` (order 2), `wc = 2 pi
/// bandwidth_hz`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurrentLoop {
    /// Corner frequency (order 1) or natural frequency (order 2) [Hz].
    pub bandwidth_hz: f64,
    /// 1 or 2 [-]; default 1.
    #[serde(default = "one")]
    pub order: u8,
    /// Damping ratio of the order-2 loop [-]; default 0.7071 (then `bandwidth_hz` is the
    /// -3 dB bandwidth). Ignored for order 1.
    #[serde(default = "sqrt_half")]
    pub damping_ratio: f64,
}

fn one() -> u8 {
    1
}
fn sqrt_half() -> f64 {
    std::f64::consts::FRAC_1_SQRT_2
}

/// Motor friction: viscous `-b w1` plus Coulomb `-Tc sign(w1)` with exact stiction.
///
/// Stick/slip (a Karnopp-type model decided at every integration sub-step): while the motor
/// is at rest it stays at rest (`w1 = 0`, the friction cancels every other torque on it) as
/// long as the magnitude of the other torques on the motor (command, springs, dampers,
/// noise) is at most `coulomb_nm`; above it, it slips in that torque's direction against
/// `-Tc sign(w1) - b w1`. When a slipping motor's velocity crosses zero within a sub-step
/// it is set to rest and the stick test applies again. No velocity scale is needed: a torque
/// below `coulomb_nm` leaves the motor exactly still (no creep).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    /// Coulomb (and breakaway) friction torque `Tc` [N m], >= 0.
    #[serde(default)]
    pub coulomb_nm: f64,
    /// Viscous friction `b` [N m s/rad], >= 0.
    #[serde(default)]
    pub viscous_nms_per_rad: f64,
}

/// Gear backlash in coupling `coupling`: with deflection `x = theta_(k+1) - theta_k`
/// (0-based bodies joined by the coupling), the spring torque is `c (x - g sign x)` for
/// `|x| > g` and 0 inside the gap `|x| <= g`; the coupling's damper acts only in contact.
/// The axis starts centred in the gap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Backlash {
    /// 0-based coupling index: 0 is `c1` between the motor and body 2; the extra mode's
    /// coupling (if any) is the last.
    pub coupling: usize,
    /// Half the gap `g` [rad] (total play `2 g`), >= 0.
    pub half_gap_rad: f64,
}

/// A hardening spring in coupling `coupling`: torque `c x (1 + (x/x_ref)^2)`, i.e.
/// `c x + c3 x^3` with `c3 = c / x_ref^2`; the tangent stiffness is `c (1 + 3 (x/x_ref)^2)`,
/// four times `c` at `x = x_ref`. With backlash on the same coupling, `x` is the deflection
/// beyond the gap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Hardening {
    /// 0-based coupling index (as [`Backlash::coupling`]).
    pub coupling: usize,
    /// Reference deflection `x_ref` [rad] > 0 where the cubic term equals the linear one.
    pub x_ref_rad: f64,
}

/// A pure time delay between the torque command and the current loop (or motor).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeDelay {
    /// Delay [s] >= 0; any value (not restricted to whole cycles): the integration grid is
    /// split at the instant the delayed command changes, so the delay is exact.
    pub delay_s: f64,
}

/// Gravity on the last body: torque `-m_g_l sin(theta_n + offset)` [N m], behaving like a
/// grounding spring of `m_g_l` [N m/rad] at small angles about the hanging position.
/// `offset_rad` is the arm's angle from hanging straight down when `theta_n = 0`; the axis
/// starts at `theta = 0`, so a non-zero offset loads it with `m_g_l sin(offset)` from the
/// start.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// `m g l` [N m] >= 0 (mass times gravity times centre-of-mass distance).
    pub m_g_l_nm: f64,
    /// Angle of the arm from hanging down at `theta_n = 0` [rad].
    #[serde(default)]
    pub offset_rad: f64,
}

/// An extra body (a mode the identification was not told about) joined to the last body
/// of the chain by a spring and damper. It becomes the last body (gravity acts on it and
/// [`super::AxisSample::load_position_rad`] is its angle).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtraMode {
    /// Inertia [kg m^2] > 0.
    pub inertia_kgm2: f64,
    /// Stiffness [N m/rad] > 0 of its spring.
    pub stiffness_nm_per_rad: f64,
    /// Damping [N m s/rad] >= 0 of its damper.
    #[serde(default)]
    pub damping_nms_per_rad: f64,
}

fn check(what: &'static str, value: f64, positive: bool) -> Result<(), PlantError> {
    let ok = value.is_finite() && if positive { value > 0.0 } else { value >= 0.0 };
    if ok {
        Ok(())
    } else {
        Err(PlantError::Parameter {
            what,
            value,
            requirement: if positive {
                "must be positive and finite"
            } else {
                "must be non-negative and finite"
            },
        })
    }
}

impl Effects {
    /// Whether any effect is on (then `flexid simulate` integrates with [`super::PlantSim`]).
    pub fn any(&self) -> bool {
        self.torque_noise_nm != 0.0
            || self.encoder_counts_per_rev.is_some()
            || self.current_loop.is_some()
            || self.friction.is_some()
            || self.backlash.is_some()
            || self.hardening_stiffness.is_some()
            || self.time_delay.is_some()
            || self.gravity.is_some()
            || self.extra_mode.is_some()
    }
}

impl PlantSpec {
    /// A spec of the chain alone (all effects off).
    pub fn linear(chain: Chain) -> Self {
        PlantSpec {
            chain,
            effects: Effects::default(),
        }
    }

    /// Parse a TOML text holding `[chain]` and optionally `[effects]`, validated.
    pub fn from_toml(text: &str) -> Result<Self, PlantError> {
        let s: PlantSpec = toml::from_str(text).map_err(|e| PlantError::Parse(e.to_string()))?;
        s.validate()?;
        Ok(s)
    }

    /// The simulated chain: the spec's chain with the extra mode (if any) appended.
    pub fn extended_chain(&self) -> Chain {
        let mut c = self.chain.clone();
        if let Some(m) = &self.effects.extra_mode {
            c.inertia_kgm2.push(m.inertia_kgm2);
            c.stiffness_nm_per_rad.push(m.stiffness_nm_per_rad);
            c.damping_nms_per_rad.push(m.damping_nms_per_rad);
        }
        c
    }

    /// Check the chain and every effect's parameters.
    pub fn validate(&self) -> Result<(), PlantError> {
        self.chain.validate()?;
        let e = &self.effects;
        check("effects.torque_noise_nm", e.torque_noise_nm, false)?;
        if e.encoder_counts_per_rev == Some(0) {
            return Err(PlantError::Parameter {
                what: "effects.encoder_counts_per_rev",
                value: 0.0,
                requirement: "must be at least 1",
            });
        }
        if let Some(m) = &e.extra_mode {
            check("effects.extra_mode.inertia_kgm2", m.inertia_kgm2, true)?;
            check(
                "effects.extra_mode.stiffness_nm_per_rad",
                m.stiffness_nm_per_rad,
                true,
            )?;
            check(
                "effects.extra_mode.damping_nms_per_rad",
                m.damping_nms_per_rad,
                false,
            )?;
        }
        let couplings = self.chain.masses() - 1 + usize::from(e.extra_mode.is_some());
        if let Some(c) = &e.current_loop {
            check("effects.current_loop.bandwidth_hz", c.bandwidth_hz, true)?;
            if !(c.order == 1 || c.order == 2) {
                return Err(PlantError::Parameter {
                    what: "effects.current_loop.order",
                    value: f64::from(c.order),
                    requirement: "must be 1 or 2",
                });
            }
            check("effects.current_loop.damping_ratio", c.damping_ratio, true)?;
        }
        if let Some(f) = &e.friction {
            check("effects.friction.coulomb_nm", f.coulomb_nm, false)?;
            check(
                "effects.friction.viscous_nms_per_rad",
                f.viscous_nms_per_rad,
                false,
            )?;
        }
        if let Some(b) = &e.backlash {
            if b.coupling >= couplings {
                return Err(PlantError::Coupling {
                    effect: "backlash",
                    index: b.coupling,
                    couplings,
                });
            }
            check("effects.backlash.half_gap_rad", b.half_gap_rad, false)?;
        }
        if let Some(h) = &e.hardening_stiffness {
            if h.coupling >= couplings {
                return Err(PlantError::Coupling {
                    effect: "hardening_stiffness",
                    index: h.coupling,
                    couplings,
                });
            }
            check("effects.hardening_stiffness.x_ref_rad", h.x_ref_rad, true)?;
        }
        if let Some(d) = &e.time_delay {
            check("effects.time_delay.delay_s", d.delay_s, false)?;
        }
        if let Some(g) = &e.gravity {
            check("effects.gravity.m_g_l_nm", g.m_g_l_nm, false)?;
            if !g.offset_rad.is_finite() {
                return Err(PlantError::Parameter {
                    what: "effects.gravity.offset_rad",
                    value: g.offset_rad,
                    requirement: "must be finite",
                });
            }
        }
        Ok(())
    }
}

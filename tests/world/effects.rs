//! The effects inside the diagnosis's library, implemented the world's own way, each as a
//! [`Knob`]: its shape drawn once per case, its size free (a typical size drawn, enlarged
//! by the case generator where it is not visible enough against the noise). Names as the
//! diagnosis's (`coulomb_friction`, ...), plus `hardening_ground`, a cubic spring to the
//! ground, whose right name is `hardening_stiffness`. Typical sizes (those of the
//! withheld-effect benchmark where it has them):
//!
//! | effect | what it is physically | size | typical |
//! |---|---|---|---|
//! | `coulomb_friction` | Stribeck friction on the motor, smooth through zero speed | Coulomb level / low level's RMS torque | 0.05-0.3 |
//! | `backlash` | play in a random coupling, contact damping ramped in | half gap / low level's RMS deflection there | 0.5-2 |
//! | `hardening_stiffness` | `c x (1 + (x/x_ref)^2)` in a random coupling | (high level's RMS deflection / x_ref)^2 | 0.04-0.44 (x_ref 1.5-5x) |
//! | `hardening_ground` | `-k3 q^3` from the load to the ground | `3 k3 sigma^2 / (J_t w_min^2)` | 0.2-2 |
//! | `time_delay` | command delay, any fraction of a sample | samples | 0.2-2 |
//! | `current_loop` | order 1 or 2 (damping 0.5-0.9) low-pass on the torque | f_max / bandwidth | 0.53-2.67 (bandwidth 0.15-0.75 fs) |
//! | `unmodelled_mode` | one more body at the load end, pair anywhere in 3 f_min .. 0.3 fs | its inertia / the load's | 0.3-1 |
//! | `gravity` | `-m g l sin q` on the load, bearing damping 5-20 % of the swing | `m g l / (J_t w_min^2)` (swing at 1-5x f_min) | 1-25 |

use super::plant::{Coupling, Friction, Gravity, GroundCubic, Law, LowPass, Plant};
use super::substeps::Peaks;
use super::visibility::Reference;
use rand::Rng;
use serde_json::json;

/// What the effects are drawn against: the nominal axis and its measurement.
#[derive(Debug, Clone)]
pub struct Context {
    pub nominal: Plant,
    pub fs_hz: f64,
    pub band_hz: [f64; 2],
    pub reference: Reference,
    /// Small-signal RMS motion at each level.
    pub motion: Vec<Peaks>,
    /// RMS motor velocity at each level [rad/s].
    pub velocity_rms_rad_s: Vec<f64>,
}

impl Context {
    pub fn low(&self) -> usize {
        0
    }
    pub fn high(&self) -> usize {
        self.reference.levels_rms_nm.len() - 1
    }
    pub fn f_max_hz(&self) -> f64 {
        self.band_hz[1]
    }
    /// The lowest excited frequency [Hz].
    pub fn f_min_hz(&self) -> f64 {
        self.band_hz[0]
    }
    /// The last body of the nominal chain (the load).
    pub fn load(&self) -> usize {
        self.nominal.bodies() - 1
    }
}

type Apply = Box<dyn Fn(&mut Plant, f64) + Send + Sync>;

/// An effect or cause with its shape drawn and its size free.
pub struct Knob {
    pub class: &'static str,
    /// The diagnosis's right answer for it alone (`unexplained` for the causes outside the
    /// library).
    pub answer: &'static str,
    /// What the size measures, with its unit.
    pub size_name: &'static str,
    /// The sizes searched.
    pub range: [f64; 2],
    pub start: f64,
    /// The sizes an axis typically has (drawn log-uniform; enlarged where that is not
    /// visible enough).
    pub typical: [f64; 2],
    /// Whether the small-signal response shows it entirely (no simulation needed).
    pub linear: bool,
    /// Everything drawn for this case but the size.
    pub shape: serde_json::Value,
    apply: Apply,
    /// The nominal chain a nominal model would make of the effect, where its physics says
    /// so (an extra body merged into the one it hangs on): a further start of the world's
    /// refit ([`super::visibility::Projector::residual_from`]).
    absorb: Option<Apply>,
}

impl Knob {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        class: &'static str,
        answer: &'static str,
        size_name: &'static str,
        range: [f64; 2],
        start: f64,
        linear: bool,
        shape: serde_json::Value,
        apply: Apply,
    ) -> Knob {
        Knob {
            class,
            answer,
            size_name,
            range,
            start,
            typical: range,
            linear,
            shape,
            apply,
            absorb: None,
        }
    }

    /// With `absorb`, the nominal chain a nominal model would make of the effect.
    pub fn absorbed_as(mut self, absorb: Apply) -> Knob {
        self.absorb = Some(absorb);
        self
    }

    /// The nominal chain `plant` moved as a nominal model would absorb the effect at
    /// `size`; false (and `plant` unchanged) where the effect names no such chain.
    pub fn absorbed(&self, plant: &mut Plant, size: f64) -> bool {
        self.absorb.as_ref().map(|a| a(plant, size)).is_some()
    }

    /// With the typical sizes `[lo, hi]`.
    pub fn typical(mut self, lo: f64, hi: f64) -> Knob {
        self.typical = [lo, hi];
        self
    }

    /// The effect at `size` added to `plant`.
    pub fn apply(&self, plant: &mut Plant, size: f64) {
        (self.apply)(plant, size)
    }
}

/// The library's effects (and the ground hardening), in the benchmark's row order.
pub const EFFECTS: [&str; 8] = [
    "coulomb_friction",
    "backlash",
    "hardening_stiffness",
    "hardening_ground",
    "time_delay",
    "current_loop",
    "unmodelled_mode",
    "gravity",
];

fn log_uniform(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo.ln()..hi.ln()).exp()
}

fn two_pi() -> f64 {
    2.0 * std::f64::consts::PI
}

/// The knob of library effect `class` on the axis of `ctx`.
pub fn effect(class: &str, ctx: &Context, rng: &mut impl Rng) -> Knob {
    let (lo, hi) = (ctx.low(), ctx.high());
    let rms_low = ctx.reference.levels_rms_nm[lo];
    let jt = ctx.nominal.total_inertia_kgm2();
    let couplings = ctx.nominal.couplings.len();
    match class {
        "coulomb_friction" => {
            // Stribeck peak 0-50 % above the Coulomb level, Stribeck speed 5-50 % of the low
            // level's RMS speed, pre-sliding regularisation 0.5-2 % of it
            let v = ctx.velocity_rms_rad_s[lo];
            let ratio = rng.random_range(1.0..1.5);
            let vs = v * log_uniform(rng, 0.05, 0.5);
            let vreg = v * log_uniform(rng, 0.005, 0.02);
            Knob::new(
                "coulomb_friction",
                "coulomb_friction",
                "coulomb_over_low_rms_torque",
                [1e-4, 0.8],
                0.1,
                false,
                json!({"static_over_coulomb": ratio, "stribeck_rad_s": vs, "regularisation_rad_s": vreg}),
                Box::new(move |p, s| {
                    let tc = s * rms_low;
                    p.friction = Some(Friction {
                        coulomb_nm: tc,
                        static_nm: ratio * tc,
                        stribeck_rad_s: vs,
                        regularisation_rad_s: vreg,
                    });
                }),
            )
            .typical(0.05, 0.3)
        }
        "backlash" => {
            let k = rng.random_range(0..couplings);
            let x = ctx.motion[lo].deflection_rad[k];
            Knob::new(
                "backlash",
                "backlash",
                "half_gap_over_low_rms_deflection",
                [0.01, 5.0],
                0.5,
                false,
                json!({"coupling": k, "low_rms_deflection_rad": x}),
                Box::new(move |p, s| {
                    let g = s * x;
                    p.couplings[k].law = Law::DeadZone {
                        half_gap_rad: g,
                        contact_ramp_rad: 0.1 * g,
                    };
                }),
            )
            .typical(0.5, 2.0)
        }
        "hardening_stiffness" => {
            let k = rng.random_range(0..couplings);
            let x = ctx.motion[hi].deflection_rad[k];
            Knob::new(
                "hardening_stiffness",
                "hardening_stiffness",
                "high_rms_deflection_over_x_ref_squared",
                [1e-4, 5.0],
                0.05,
                false,
                json!({"coupling": k, "high_rms_deflection_rad": x}),
                Box::new(move |p, s| {
                    p.couplings[k].law = Law::Hardening {
                        x_ref_rad: x / s.sqrt(),
                    };
                }),
            )
            .typical(0.04, 0.44)
        }
        "hardening_ground" => {
            // on the load; the size is the equivalent stiffness 3 k3 sigma^2 at the high
            // level against the total inertia at the lowest excited frequency
            let b = ctx.load();
            let sigma = ctx.motion[hi].position_rad[b];
            let k_ref = jt * (two_pi() * ctx.f_min_hz()).powi(2);
            Knob::new(
                "hardening_ground",
                "hardening_stiffness",
                "equivalent_stiffness_over_jt_w_min_squared",
                [1e-3, 1e3],
                1.0,
                false,
                json!({"body": b, "high_rms_position_rad": sigma, "reference_stiffness_nm_per_rad": k_ref}),
                Box::new(move |p, s| {
                    p.ground_cubic = Some(GroundCubic {
                        body: b,
                        cubic_nm_per_rad3: s * k_ref / (3.0 * sigma * sigma),
                    });
                }),
            )
            .typical(0.2, 2.0)
        }
        "time_delay" => {
            let ts = 1.0 / ctx.fs_hz;
            Knob::new(
                "time_delay",
                "time_delay",
                "delay_samples",
                [0.01, 4.0],
                0.5,
                true,
                json!({}),
                Box::new(move |p, s| p.drive.delay_s = s * ts),
            )
            .typical(0.2, 2.0)
        }
        "current_loop" => {
            let order = rng.random_range(1..=2u8);
            let zeta = rng.random_range(0.5..0.9);
            let fmax = ctx.f_max_hz();
            Knob::new(
                "current_loop",
                "current_loop",
                "f_max_over_bandwidth",
                [0.01, 5.0],
                0.5,
                true,
                json!({"order": order, "damping_ratio": zeta}),
                Box::new(move |p, s| {
                    p.drive.current_loop = Some(LowPass {
                        order,
                        bandwidth_hz: fmax / s,
                        damping_ratio: zeta,
                    })
                }),
            )
            .typical(0.533, 2.667)
        }
        "unmodelled_mode" => {
            // a further body at the load end, its two-body frequency with the load anywhere
            // from 3x the lowest line to 0.3 fs, 0.5-4 % damping
            let b = ctx.load();
            let jl = ctx.nominal.inertia_kgm2[b];
            let f = log_uniform(rng, 3.0 * ctx.f_min_hz(), 0.3 * ctx.fs_hz);
            let zeta = rng.random_range(0.005..0.04);
            Knob::new(
                "unmodelled_mode",
                "unmodelled_mode",
                "extra_inertia_over_load_inertia",
                [1e-4, 3.0],
                0.1,
                true,
                json!({"two_body_frequency_hz": f, "damping_ratio": zeta, "load_inertia_kgm2": jl}),
                Box::new(move |p, s| {
                    let je = s * jl;
                    let pair = 1.0 / (1.0 / je + 1.0 / jl);
                    let c = pair * (two_pi() * f).powi(2);
                    p.inertia_kgm2.push(je);
                    p.couplings.push(Coupling {
                        stiffness_nm_per_rad: c,
                        damping_nms_per_rad: 2.0 * zeta * (c * pair).sqrt(),
                        law: Law::Linear,
                    });
                }),
            )
            .typical(0.3, 1.0)
            // below its pair, the extra body moves with the load
            .absorbed_as(Box::new(move |p, s| p.inertia_kgm2[b] += s * jl))
        }
        "gravity" => {
            // the load swings; the size is m g l against the total inertia at the lowest
            // excited frequency; its bearing damps the swinging mode by 5-20 %
            let b = ctx.load();
            let zeta = rng.random_range(0.05..0.2);
            let k_ref = jt * (two_pi() * ctx.f_min_hz()).powi(2);
            Knob::new(
                "gravity",
                "gravity",
                "m_g_l_over_jt_w_min_squared",
                [1e-3, 1e4],
                1.0,
                true,
                json!({"body": b, "swing_damping_ratio": zeta, "reference_stiffness_nm_per_rad": k_ref}),
                Box::new(move |p, s| {
                    let mgl = s * k_ref;
                    p.gravity = Some(Gravity {
                        body: b,
                        m_g_l_nm: mgl,
                        bearing_damping_nms_per_rad: 2.0 * zeta * (mgl * jt).sqrt(),
                    });
                }),
            )
            .typical(1.0, 25.0)
        }
        other => panic!("not a library effect: {other}"),
    }
}

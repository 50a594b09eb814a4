//! Causes outside the diagnosis's library, whose right answer is `unexplained` with a gap
//! band overlapping where they act. Each is a [`Knob`] like the library's effects; where it
//! acts on the FRF ([`super::visibility::acting_band`]) is written into the truth file.
//!
//! Left out on purpose: the motor's housing on a compliant bracket (the encoder reading
//! the rotor against it). Its FRF is the chain's compliance plus a grounded oscillator's,
//! a driving-point compliance with positive residues whose poles and zeros interlace,
//! which a chain of one more body realises exactly (Foster, Cauer): on these data
//! `unmodelled_mode` is as right as any answer. The position low-pass stays although on
//! the torque -> position FRF alone it has a current loop's shape: the recordings carry
//! `torque_actual_nm`, which a current loop changes and an encoder filter does not.

use super::effects::{Context, Knob};
use super::plant::{Cogging, LowPass, Notch, Resonator};
use rand::Rng;
use serde_json::json;

/// The causes, in the benchmark's row order.
pub const CAUSES: [&str; 6] = [
    "notch_filter",
    "position_lowpass",
    "cogging",
    "encoder_shaft",
    "encoder_play",
    "amplifier_dead_zone",
];

fn log_uniform(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo.ln()..hi.ln()).exp()
}

/// The knob of cause `class` on the axis of `ctx`.
pub fn cause(class: &str, ctx: &Context, rng: &mut impl Rng) -> Knob {
    let (fmin, fmax) = (ctx.f_min_hz(), ctx.f_max_hz());
    let rms_low = ctx.reference.levels_rms_nm[ctx.low()];
    match class {
        // A notch filter left in the drive's torque reference (tuned for another load, or
        // for a resonance that has moved): a band-stop at a frequency anywhere from 3x the
        // lowest line to 0.8x the highest, pole damping 0.05-0.4 (its width); the size is
        // its depth, 1 - zz/zp.
        "notch_filter" => {
            let f = log_uniform(rng, 3.0 * fmin, 0.8 * fmax);
            let zp = log_uniform(rng, 0.05, 0.4);
            Knob::new(
                "notch_filter",
                "unexplained",
                "depth_one_minus_zero_over_pole_damping",
                [0.005, 0.99],
                0.5,
                true,
                json!({"centre_hz": f, "pole_damping_ratio": zp}),
                Box::new(move |p, s| {
                    p.drive.notch = Some(Notch {
                        centre_hz: f,
                        pole_damping_ratio: zp,
                        zero_damping_ratio: zp * (1.0 - s),
                    })
                }),
            )
            .typical(0.5, 0.95)
        }
        // The drive's encoder/velocity filter on the measured position only (order 1, or 2
        // Butterworth): the torque and the torque reading do not see it. On the torque ->
        // position FRF alone it has the shape of a current loop; `torque_actual_nm` tells
        // them apart. Size f_max / corner.
        "position_lowpass" => {
            let order = rng.random_range(1..=2u8);
            Knob::new(
                "position_lowpass",
                "unexplained",
                "f_max_over_corner",
                [0.005, 5.0],
                0.3,
                true,
                json!({"order": order}),
                Box::new(move |p, s| {
                    p.sensor.lowpass = Some(LowPass {
                        order,
                        bandwidth_hz: fmax / s,
                        damping_ratio: std::f64::consts::FRAC_1_SQRT_2,
                    })
                }),
            )
            .typical(0.25, 1.0)
        }
        // Cogging torque of the motor's magnets and slots, 6-60 detents per revolution, the
        // axis resting in a detent; the size is its amplitude over the low level's RMS
        // torque (typically 2-20 %).
        "cogging" => {
            let n = rng.random_range(6..=60u32) as f64;
            Knob::new(
                "cogging",
                "unexplained",
                "amplitude_over_low_rms_torque",
                [1e-4, 3.0],
                0.05,
                false,
                json!({"periods_per_rev": n}),
                Box::new(move |p, s| {
                    p.cogging = Some(Cogging {
                        amplitude_nm: s * rms_low,
                        periods_per_rev: n,
                    })
                }),
            )
            .typical(0.02, 0.2)
        }
        // The encoder's disc on a compliant shaft (a long coupling, a loose clamp): a
        // lightly damped resonance (2-10 %) in the measurement only; size f_max / its
        // frequency.
        "encoder_shaft" => {
            let zeta = log_uniform(rng, 0.02, 0.1);
            Knob::new(
                "encoder_shaft",
                "unexplained",
                "f_max_over_shaft_frequency",
                [0.01, 5.0],
                0.5,
                true,
                json!({"damping_ratio": zeta}),
                Box::new(move |p, s| {
                    p.sensor.shaft = Some(Resonator {
                        frequency_hz: fmax / s,
                        damping_ratio: zeta,
                    })
                }),
            )
            .typical(0.33, 1.0)
        }
        // Play in the encoder's coupling: the disc lags the shaft by up to the half play
        // after every reversal (the hysteresis of a loose coupling), in the measurement
        // only. Size: the half play over the high level's RMS motor angle (typically
        // 0.1-1 %).
        "encoder_play" => {
            let sigma = ctx.motion[ctx.high()].position_rad[0];
            Knob::new(
                "encoder_play",
                "unexplained",
                "half_play_over_high_rms_motor_angle",
                [1e-5, 0.5],
                0.003,
                false,
                json!({"high_rms_motor_angle_rad": sigma}),
                Box::new(move |p, s| p.sensor.half_play_rad = s * sigma),
            )
            .typical(0.001, 0.01)
        }
        // The power stage's dead zone (crossover distortion): torques below d are not
        // produced, larger ones lose d. Size d over the low level's RMS torque.
        "amplifier_dead_zone" => Knob::new(
            "amplifier_dead_zone",
            "unexplained",
            "dead_zone_over_low_rms_torque",
            [1e-4, 1.0],
            0.05,
            false,
            json!({}),
            Box::new(move |p, s| p.drive.dead_zone_nm = s * rms_low),
        )
        .typical(0.02, 0.2),
        other => panic!("not a cause: {other}"),
    }
}

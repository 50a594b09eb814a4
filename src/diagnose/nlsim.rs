//! The diagnosis's own time-domain simulation of the chain with an amplitude-dependent
//! effect, on the recorded excitation: the linear chain discretised exactly (ZOH) on
//! `substeps` sub-steps per sample, the effect's torque held over each sub-step
//! (explicit for the spring nonlinearities; semi-implicit for friction: over each sub-step
//! the Coulomb torque, bounded by `Tc`, is the one that stops the motor if it can, so
//! stiction needs no velocity scale). Deliberately not [`crate::plant::PlantSim`] (RK4 of
//! the full nonlinear equations), which generates the benchmark's data.

use super::lti::{zoh, LinExt};
use crate::analysis::estimate_frf;
use crate::recording::{MotionSignal, Recording};
use num_complex::Complex64;

/// The amplitude-dependent effect simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Nl {
    None,
    /// Coulomb friction `tc` [N m] on the motor (viscous part in [`LinExt::motor_b`]).
    Friction {
        tc: f64,
    },
    /// Dead zone of half-width `g` [rad] in coupling `k` (0-based).
    Backlash {
        k: usize,
        g: f64,
    },
    /// Spring torque `c x (1 + (x/xref)²)` in coupling `k`.
    Hardening {
        k: usize,
        xref: f64,
    },
}

/// Simulated motor position and velocity at the sample instants, and the RMS deflection
/// of each coupling.
pub struct SimOut {
    pub pos: Vec<f64>,
    pub vel: Vec<f64>,
    pub defl_rms: Vec<f64>,
}

pub fn simulate(lin: &LinExt, nl: Nl, u: &[f64], fs: f64, substeps: usize) -> SimOut {
    let ch = &lin.chain;
    let n = ch.masses();
    let k = match nl {
        Nl::Backlash { k, .. } | Nl::Hardening { k, .. } => k.min(n.saturating_sub(2)),
        _ => 0,
    };
    let mut plain = lin.clone();
    plain.current_loop = None;
    let (a, b) = plain.continuous(if n > 1 { Some(k) } else { None });
    let sub = substeps.max(1);
    let (ad, bd) = zoh(&a, &b, 1.0 / fs / sub as f64);
    let ns = a.nrows();
    let adv: Vec<f64> = (0..ns * ns).map(|i| ad[(i / ns, i % ns)]).collect();
    let col = |j: usize| -> Vec<f64> {
        if j < bd.ncols() {
            (0..ns).map(|r| bd[(r, j)]).collect()
        } else {
            vec![0.0; ns]
        }
    };
    let (bu, bm, bc) = (col(0), col(1), col(2));
    let bm = if n > 1 { bm } else { bu.clone() };
    let (c, d) = if n > 1 {
        (ch.stiffness_nm_per_rad[k], ch.damping_nms_per_rad[k])
    } else {
        (0.0, 0.0)
    };
    let mut x: Vec<f64> = vec![0.0; ns];
    let mut xn: Vec<f64> = vec![0.0; ns];
    let mut pos = Vec::with_capacity(u.len());
    let mut vel = Vec::with_capacity(u.len());
    let mut dsum = vec![0.0; n.saturating_sub(1)];
    for &uk in u {
        pos.push(x[0]);
        vel.push(x[n]);
        for (i, s) in dsum.iter_mut().enumerate() {
            let dx = x[i + 1] - x[i];
            *s += dx * dx;
        }
        for _ in 0..sub {
            let fc = if n > 1 {
                let (dx, dv) = (x[k + 1] - x[k], x[n + k + 1] - x[n + k]);
                match nl {
                    Nl::Backlash { g, .. } => {
                        if dx.abs() < g {
                            -c * dx - d * dv
                        } else {
                            -c * g * dx.signum()
                        }
                    }
                    Nl::Hardening { xref, .. } => {
                        let r = dx / xref;
                        c * dx * r * r
                    }
                    _ => 0.0,
                }
            } else {
                0.0
            };
            for r in 0..ns {
                let row = &adv[r * ns..(r + 1) * ns];
                let mut s = bu[r] * uk + bc[r] * fc;
                for (a, xv) in row.iter().zip(&x) {
                    s += a * xv;
                }
                xn[r] = s;
            }
            if let Nl::Friction { tc } = nl {
                let b = bm[n];
                if b != 0.0 {
                    let tf = (-xn[n] / b).clamp(-tc, tc);
                    for r in 0..ns {
                        xn[r] += bm[r] * tf;
                    }
                }
            }
            std::mem::swap(&mut x, &mut xn);
        }
        if !x.iter().all(|v| v.is_finite() && v.abs() < 1e12) {
            // unstable (a spring stiffened beyond the step): no model
            let bad = vec![f64::NAN; u.len()];
            return SimOut {
                pos: bad.clone(),
                vel: bad,
                defl_rms: vec![f64::NAN; n.saturating_sub(1)],
            };
        }
    }
    let len = u.len().max(1) as f64;
    SimOut {
        pos,
        vel,
        defl_rms: dsum.iter().map(|s| (s / len).sqrt()).collect(),
    }
}

/// The FRF of the simulated response, estimated exactly as the measurement's (same
/// recording description, same estimator), on the lines `keep` of that estimate.
pub fn sim_frf(
    rec: &Recording,
    band: Option<[f64; 2]>,
    keep: &[usize],
    out: &SimOut,
) -> Option<Vec<Complex64>> {
    let mut r = rec.clone();
    let n = out.pos.len();
    r.time_s.truncate(n);
    r.torque_cmd_nm.truncate(n);
    if n < rec.len() {
        // a shortened simulation (the search): its steady periods only
        if let Some(e) = r.sidecar.excitation.as_mut() {
            if e.period_samples > 0 {
                e.periods = (n / e.period_samples)
                    .saturating_sub(e.transient_periods)
                    .max(1);
            }
        }
    }
    match rec.preferred_motion()?.0 {
        MotionSignal::Position => {
            r.position_rad = Some(out.pos.clone());
            r.velocity_rad_s = None;
        }
        MotionSignal::Velocity => {
            r.velocity_rad_s = Some(out.vel.clone());
            r.position_rad = None;
        }
        MotionSignal::Acceleration => return None,
    }
    for v in [&mut r.position_rad, &mut r.velocity_rad_s]
        .into_iter()
        .flatten()
    {
        v.truncate(n);
    }
    r.acceleration_rad_s2 = None;
    let e = estimate_frf(&r, band).ok()?;
    keep.iter().map(|&i| e.frf.h.get(i).copied()).collect()
}

//! A level's swept-sine estimator planned once for the search's simulations
//! ([`LpmPlan`]): the search estimates the simulated response of hundreds of candidates to
//! the same recorded sweep, and the local polynomial method's planning, its input's
//! transform and every window's least squares, redone each time, were half of a swept
//! sine's diagnosis. Planned, each estimate is one transform of the simulated motion and
//! a weighted sum per line, equal to the full estimate to rounding
//! (`a_planned_sweep_estimate_is_the_full_one`).

use super::nlsim::SimOut;
use crate::analysis::{motion_frf_kind, single_sweep};
use crate::frf::{differenced_velocity_into, FrfKind, LpmPlan, LpmScratch};
use crate::recording::{MotionSignal, Recording};
use num_complex::Complex64;
use std::cell::RefCell;
use std::sync::OnceLock;

/// What a plan was made for: the address and length of the recording's torque command,
/// the band's bits and the motion estimated.
type Key = (usize, usize, Option<[u64; 2]>, MotionSignal);

/// The kept plan of one level's recording ([`super::Level::rec`]).
#[derive(Debug, Default)]
pub struct SweepPlan {
    slot: OnceLock<(Key, Option<LpmPlan>)>,
}

impl Clone for SweepPlan {
    /// A clone plans afresh (the plan is made again on first use).
    fn clone(&self) -> Self {
        SweepPlan::default()
    }
}

thread_local! {
    /// The buffers of the planned estimates: the differenced motion, the transform's.
    static SCRATCH: RefCell<(Vec<f64>, LpmScratch)> = RefCell::new(Default::default());
}

/// The motion a sweep's estimate reads and the kind of its FRF
/// ([`crate::analysis::motion_frf_kind`]); `None` for an acceleration, which the
/// simulation does not give.
fn motion_kind(rec: &Recording) -> Option<(MotionSignal, FrfKind)> {
    match rec.preferred_motion()?.0 {
        MotionSignal::Acceleration => None,
        m => Some((m, motion_frf_kind(m))),
    }
}

impl SweepPlan {
    /// The plan of `rec` in `band` (the user's, else the sweep's own, as the estimate
    /// takes it), when `rec` is a single sweep of a position or velocity; kept for the
    /// next call with the same recording and band.
    fn get(&self, rec: &Recording, band: Option<[f64; 2]>) -> Option<&LpmPlan> {
        let info = single_sweep(rec)?;
        let (motion, kind) = motion_kind(rec)?;
        let band = band.or(info.band_hz);
        let key: Key = (
            rec.torque_cmd_nm.as_ptr() as usize,
            rec.len(),
            band.map(|[a, b]| [a.to_bits(), b.to_bits()]),
            motion,
        );
        let make = || LpmPlan::new(&rec.torque_cmd_nm, rec.sample_rate_hz, kind, band).ok();
        let (k, plan) = self.slot.get_or_init(|| (key, make()));
        // another recording or band than the kept plan's: no plan (the full estimate)
        (*k == key).then_some(plan.as_ref()).flatten()
    }

    /// The simulated motion `out` of the whole of `rec` estimated as the measurement's
    /// sweep, on the lines `keep` of that estimate; `None` where no plan applies (not a
    /// sweep, a simulation of another length) or a line's estimate is zero or not finite,
    /// which the full estimate would have dropped: the caller estimates in full then.
    pub fn sim_frf(
        &self,
        rec: &Recording,
        band: Option<[f64; 2]>,
        keep: &[usize],
        out: &SimOut,
    ) -> Option<Vec<Complex64>> {
        let plan = self.get(rec, band)?;
        let (motion, _) = motion_kind(rec)?;
        SCRATCH.with(|s| {
            let (diff, scratch) = &mut *s.borrow_mut();
            let y: &[f64] = match motion {
                MotionSignal::Position => {
                    diff.resize(out.pos.len(), 0.0);
                    differenced_velocity_into(&out.pos, rec.sample_rate_hz, None, diff);
                    diff
                }
                _ => &out.vel,
            };
            let mut h = Vec::with_capacity(plan.freq_hz().len());
            plan.estimate_into(y, scratch, &mut h).ok()?;
            if h.iter()
                .any(|v| !(v.re.is_finite() && v.im.is_finite()) || v.norm() == 0.0)
            {
                return None;
            }
            keep.iter().map(|&i| h.get(i).copied()).collect()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::estimate_motion;
    use crate::diagnose::lti::LinExt;
    use crate::diagnose::nlsim::{sim_frf, simulate, Nl};
    use crate::excitation::ChirpDesign;
    use crate::model::Chain;

    /// A swept sine's simulated response estimated through the plan is the full estimate
    /// (the same lines, the values to rounding), for a position and a velocity, with and
    /// without a band; a recording of another excitation has no plan.
    #[test]
    fn a_planned_sweep_estimate_is_the_full_one() {
        let fs = 1000.0;
        let mut c = ChirpDesign::new(fs, 2.0, 300.0, 8.0, 0.5);
        c.taper_s = 0.4;
        let chirp = c.generate().unwrap();
        let chain = Chain::new(vec![1e-3, 2e-3], vec![300.0], vec![0.01]).unwrap();
        let lin = LinExt::nominal(chain);
        let u = chirp.signal.clone();
        let out = simulate(&lin, Nl::Friction { tc: 0.02 }, &u, fs, 4);
        assert!(out.pos.iter().all(|v| v.is_finite()));
        for motion in [MotionSignal::Position, MotionSignal::Velocity] {
            let mut rec =
                Recording::of_position(fs, u.clone(), out.pos.clone(), Some(chirp.info()));
            if motion == MotionSignal::Velocity {
                rec.position_rad = None;
                rec.velocity_rad_s = Some(out.vel.clone());
            }
            let signal = if motion == MotionSignal::Velocity {
                &out.vel
            } else {
                &out.pos
            };
            for band in [None, Some([5.0, 250.0])] {
                let lines = estimate_motion(&rec, motion, signal, None, band)
                    .unwrap()
                    .frf
                    .h
                    .len();
                let keep: Vec<usize> = (0..lines).collect();
                let full = sim_frf(&rec, band, &keep, &out).unwrap();
                let plan = SweepPlan::default();
                let planned = plan.sim_frf(&rec, band, &keep, &out).expect("a plan");
                assert_eq!(planned.len(), full.len());
                for (p, f) in planned.iter().zip(&full) {
                    assert!(
                        (p - f).norm() <= 1e-8 * f.norm(),
                        "{motion:?} {band:?}: {p} vs {f}"
                    );
                }
                // kept: the same plan answers again; another band gets none
                assert!(plan.sim_frf(&rec, band, &keep, &out).is_some());
                assert!(plan
                    .sim_frf(&rec, Some([7.0, 200.0]), &keep, &out)
                    .is_none());
            }
        }
        // a recording of another excitation has no plan
        let mut rec = Recording::of_position(fs, u.clone(), out.pos.clone(), Some(chirp.info()));
        rec.sidecar.excitation = None;
        assert!(SweepPlan::default()
            .sim_frf(&rec, None, &[0], &out)
            .is_none());
    }
}

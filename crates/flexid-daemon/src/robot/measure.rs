//! One pose of a robot measured through its drives: orthogonal random-phase multisines on
//! every axis under the holding loop ([`flexid_sweep::run_multi_sweep`]), over any group
//! of drives whose set-points share one SYNC, then the N x N FRF matrix with its variance.

use std::sync::atomic::AtomicBool;

use flexid_canopen::MultiAxisDrive;
use flexid_core::frf::MimoFrf;
use flexid_core::manipulator::measure::MeasureOptions;
use flexid_core::manipulator::{PositionLoop, RigidPose};
use flexid_sweep::{run_multi_sweep, MultiProgress, MultiSweepOutcome, MultiSweepPlan, Pacing};

/// Errors of a pose measurement.
#[derive(Debug, thiserror::Error)]
pub enum MeasurePoseError {
    /// The excitation could not be designed.
    #[error("pose {pose}: excitation: {detail}")]
    Excitation { pose: String, detail: String },
    /// The sweep stopped before its end (the record so far is in the outcome).
    #[error("pose {pose}: sweep stopped: {reason}")]
    Stopped {
        pose: String,
        reason: String,
        outcome: Box<MultiSweepOutcome>,
    },
    /// The FRF matrix could not be estimated.
    #[error("pose {pose}: estimate: {detail}")]
    Estimate { pose: String, detail: String },
}

/// The plan measuring `pose` as `opts` says (its multisines, periods, loop bandwidth;
/// the encoder noise is the drives' own) at `pacing`.
pub fn plan_pose(
    name: &str,
    pose: &RigidPose,
    opts: &MeasureOptions,
    pacing: Pacing,
) -> Result<MultiSweepPlan, MeasurePoseError> {
    let excitation = opts
        .excitation(pose.axes())
        .map_err(|e| MeasurePoseError::Excitation {
            pose: name.to_string(),
            detail: e.to_string(),
        })?;
    Ok(MultiSweepPlan::new(
        excitation,
        opts.transient_periods,
        opts.periods,
        PositionLoop::for_pose(pose, opts.loop_bandwidth_hz),
        pacing,
    ))
}

/// Runs `plan` on the enabled `group` and estimates the FRF matrix. The caller disables
/// the drives afterwards.
pub fn measure_pose<D: MultiAxisDrive>(
    name: &str,
    group: &mut D,
    plan: &MultiSweepPlan,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&MultiProgress),
) -> Result<(MultiSweepOutcome, MimoFrf), MeasurePoseError> {
    let outcome = run_multi_sweep(group, plan, stop, progress);
    if !outcome.complete() {
        return Err(MeasurePoseError::Stopped {
            pose: name.to_string(),
            reason: outcome.reason.text(),
            outcome: Box::new(outcome),
        });
    }
    let frf = outcome
        .estimate(plan)
        .map_err(|e| MeasurePoseError::Estimate {
            pose: name.to_string(),
            detail: e.to_string(),
        })?;
    Ok((outcome, frf))
}

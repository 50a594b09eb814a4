//! One multi-axis measurement: orthogonal random-phase multisines on every axis at once
//! (the paper's section 3, `flexid_core::excitation::orthogonal`), added to the torque of
//! a low-bandwidth position loop that holds the arm at its pose, streamed to a group of
//! drives whose set-points act in the same cycle ([`MultiAxisDrive`]); every cycle's
//! set-points and motor positions recorded, the torques ramped to zero at the end.
//!
//! The experiments run back to back, each for `transient_periods + periods` periods; the
//! transient periods let the previous experiment's response die out (the estimate leaves
//! them out). The holding loop is a PD on each motor's deviation from where it was at the
//! first cycle (a real arm is measured under its position controller; gravity makes most
//! poses unstable in open loop: `../shared/design/multiaxis.md`, fact 1). The recorded
//! torque is the total set-point sent, loop included (the direct method).

use super::plan::Pacing;
use super::run::{Schedule, StopReason};
use flexid_canopen::{Counters, Feedback, MultiAxisDrive};
use flexid_core::excitation::OrthogonalMultisine;
use flexid_core::frf::{estimate_from_positions, MimoError, MimoEstimator, MimoFrf};
use flexid_core::manipulator::PositionLoop;
use flexid_core::recording::RecordingEnd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// A planned multi-axis sweep.
#[derive(Debug, Clone)]
pub struct MultiSweepPlan {
    /// The orthogonal multisines (one signal per axis and experiment).
    pub excitation: OrthogonalMultisine,
    /// Periods per experiment left to settle (recorded, not averaged).
    pub transient_periods: usize,
    /// Periods per experiment averaged.
    pub periods: usize,
    /// The holding loop's gains (motor side, per axis).
    pub hold: PositionLoop,
    /// Pacing of the cycles.
    pub pacing: Pacing,
    /// Cycles over which the torques are ramped to zero at the end (not recorded).
    pub ramp_cycles: usize,
    /// Stop when any motor's |velocity| exceeds this [rad/s].
    pub max_speed_rad_s: f64,
    /// Stop when any motor leaves its start position by more than this [rad] (the holding
    /// loop lost the arm).
    pub max_excursion_rad: f64,
    /// Stop after this much wall time (none: no limit).
    pub max_duration: Option<Duration>,
    /// Stop when more feedback messages than this are lost, all axes together.
    pub max_lost_tpdos: u64,
    /// Lock-step: how long one cycle's feedback is awaited.
    pub feedback_timeout: Duration,
}

impl MultiSweepPlan {
    /// A plan with the default limits: ramp over 50 ms, speed limit 100 rad/s, excursion
    /// limit 2 rad (motor side), duration 3 x the planned one + 10 s, lost-feedback budget
    /// 0.5 % of all feedback (at least 20), lock-step feedback timeout 50 ms.
    pub fn new(
        excitation: OrthogonalMultisine,
        transient_periods: usize,
        periods: usize,
        hold: PositionLoop,
        pacing: Pacing,
    ) -> Self {
        let fs = excitation.sample_rate_hz;
        let mut plan = MultiSweepPlan {
            excitation,
            transient_periods,
            periods,
            hold,
            pacing,
            ramp_cycles: ((0.05 * fs).round() as usize).max(5),
            max_speed_rad_s: 100.0,
            max_excursion_rad: 2.0,
            max_duration: None,
            max_lost_tpdos: 0,
            feedback_timeout: Duration::from_secs_f64((10.0 / fs).max(0.05)),
        };
        plan.max_duration = Some(Duration::from_secs_f64(3.0 * plan.duration_s() + 10.0));
        plan.max_lost_tpdos = (plan.cycles() as u64 * plan.axes() as u64 / 200).max(20);
        plan
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.excitation.axes
    }

    /// Cycles per experiment.
    pub fn cycles_per_experiment(&self) -> usize {
        (self.transient_periods + self.periods) * self.excitation.period_samples()
    }

    /// Cycles planned (without the ramp).
    pub fn cycles(&self) -> usize {
        self.excitation.experiments() * self.cycles_per_experiment()
    }

    /// Planned duration at the cycle rate [s].
    pub fn duration_s(&self) -> f64 {
        self.cycles() as f64 / self.excitation.sample_rate_hz
    }

    /// The multisine torque of axis `axis` at cycle `k` [N m].
    fn excitation_nm(&self, k: usize, axis: usize) -> f64 {
        let per = self.cycles_per_experiment();
        let n = self.excitation.period_samples();
        self.excitation.period(k / per, axis)[(k % per) % n]
    }
}

/// What a multi-axis sweep recorded: per axis, the set-point and motor position of every
/// cycle (deviations of the position from the first cycle's).
#[derive(Debug, Clone, PartialEq)]
pub struct MultiAxisRecord {
    /// Cycle rate [Hz].
    pub sample_rate_hz: f64,
    /// Per axis: the torque set-point sent [N m].
    pub torque_nm: Vec<Vec<f64>>,
    /// Per axis: the motor position [rad] minus its position at the first cycle.
    pub position_rad: Vec<Vec<f64>>,
    /// Per axis: the motor position at the first cycle [rad] (the pose held).
    pub start_position_rad: Vec<f64>,
}

impl MultiAxisRecord {
    /// Cycles recorded.
    pub fn len(&self) -> usize {
        self.torque_nm.first().map_or(0, Vec::len)
    }

    /// Whether nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Progress, reported after every period.
#[derive(Debug, Clone, Copy)]
pub struct MultiProgress {
    /// Cycles done and planned.
    pub cycle: u64,
    pub total: u64,
    /// The experiment running (from 0) and how many there are.
    pub experiment: usize,
    pub experiments: usize,
    /// Wall time since the first cycle.
    pub elapsed: Duration,
}

/// What a multi-axis sweep measured and how it ended.
#[derive(Debug, Clone)]
pub struct MultiSweepOutcome {
    /// The cycles recorded (all planned ones when complete).
    pub record: MultiAxisRecord,
    /// Why it stopped.
    pub reason: StopReason,
    /// Where and why it ended.
    pub end: RecordingEnd,
    /// Per axis: the counters of the exchange at the end.
    pub counters: Vec<Counters>,
    /// Wall time of the recorded cycles.
    pub elapsed: Duration,
    /// Cycles started more than half a period behind the real-time schedule.
    pub overruns: u64,
    /// Cycles run in the ramp to zero torque.
    pub ramp_cycles: usize,
    /// Why the ramp did not finish, if it did not.
    pub ramp_error: Option<String>,
}

impl MultiSweepOutcome {
    /// True when the planned excitation ran to its end.
    pub fn complete(&self) -> bool {
        self.reason == StopReason::Complete
    }

    /// The N x N FRF matrix (motor torques to motor speeds) with its variance from the
    /// recorded cycles of `plan` (the one that was run): the transient periods left out,
    /// the speed the backward difference of the motor positions. A sweep cut short gives
    /// the estimate of the periods it holds, or the estimator's error when an experiment
    /// has none.
    pub fn estimate(&self, plan: &MultiSweepPlan) -> Result<MimoFrf, MimoError> {
        let estimator = MimoEstimator::from_multisine(&plan.excitation)?
            .with_transient_periods(plan.transient_periods);
        estimate_from_positions(
            estimator,
            self.record.sample_rate_hz,
            plan.transient_periods + plan.periods,
            &self.record.torque_nm,
            &self.record.position_rad,
        )
    }
}

/// Runs `plan` on an enabled group of drives: one cycle per planned sample, every one
/// recorded (buffers allocated up front: the loop does not allocate), then the torques
/// ramped from their last values to zero unless a drive failed. `stop` is polled every
/// cycle; `progress` is called after every period. The caller disables the drives.
pub fn run_multi_sweep<D: MultiAxisDrive>(
    drive: &mut D,
    plan: &MultiSweepPlan,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&MultiProgress),
) -> MultiSweepOutcome {
    let axes = plan.axes();
    let n = plan.cycles();
    let fs = plan.excitation.sample_rate_hz;
    let period_samples = plan.excitation.period_samples();
    let mut record = MultiAxisRecord {
        sample_rate_hz: fs,
        torque_nm: (0..axes).map(|_| Vec::with_capacity(n)).collect(),
        position_rad: (0..axes).map(|_| Vec::with_capacity(n)).collect(),
        start_position_rad: vec![0.0; axes],
    };
    let mut fb = vec![Feedback::none(Instant::now()); axes];
    let (mut p, mut p_prev, mut hold, mut torque, mut last) = (
        vec![0.0; axes],
        vec![0.0; axes],
        vec![0.0; axes],
        vec![0.0; axes],
        vec![0.0; axes],
    );
    // the motor positions at the first cycle (the pose held)
    let mut origin = vec![0.0; axes];
    let mut schedule = Schedule::new(drive.cycle_period());
    let mut reason = StopReason::Complete;
    let mut stop_cycle = n as u64;
    let t0 = Instant::now();
    if drive.axes() != axes {
        reason = StopReason::DriveError(format!(
            "the excitation has {axes} axes, the drive group {}",
            drive.axes()
        ));
        stop_cycle = 0;
    }
    let cycles = if reason == StopReason::Complete { n } else { 0 };
    for k in 0..cycles {
        if stop.load(Ordering::Relaxed) {
            reason = StopReason::Interrupted;
            stop_cycle = k as u64;
            break;
        }
        let now = Instant::now();
        if let Some(limit) = plan.max_duration {
            if now.duration_since(t0) >= limit {
                reason = StopReason::DurationLimit(limit);
                stop_cycle = k as u64;
                break;
            }
        }
        plan.hold.torque(&p, &p_prev, fs, &mut hold);
        for (i, t) in torque.iter_mut().enumerate() {
            *t = hold[i] + plan.excitation_nm(k, i);
        }
        let deadline = match plan.pacing {
            Pacing::Realtime => schedule.next_deadline(),
            Pacing::Lockstep => now + plan.feedback_timeout,
        };
        if let Err(e) = drive.cycle(&torque, deadline, &mut fb) {
            reason = StopReason::of_error(&e);
            stop_cycle = k as u64;
            break;
        }
        if k == 0 {
            for (o, f) in origin.iter_mut().zip(&fb) {
                *o = f.position_rad;
            }
        }
        p_prev.copy_from_slice(&p);
        for i in 0..axes {
            p[i] = fb[i].position_rad - origin[i];
            record.torque_nm[i].push(fb[i].torque_setpoint_nm);
            record.position_rad[i].push(p[i]);
        }
        if let Some(r) = limits(plan, &fb, &p) {
            reason = r;
            stop_cycle = k as u64;
            break;
        }
        if (k + 1) % period_samples == 0 || k + 1 == n {
            progress(&MultiProgress {
                cycle: (k + 1) as u64,
                total: n as u64,
                experiment: k / plan.cycles_per_experiment(),
                experiments: plan.excitation.experiments(),
                elapsed: t0.elapsed(),
            });
        }
        if plan.pacing == Pacing::Realtime {
            schedule.wait();
        }
    }
    let elapsed = t0.elapsed();
    record.start_position_rad = origin;

    // Ramp every torque to zero (not recorded) unless a drive is gone or faulted; the
    // holding loop stays on (a released arm would fall).
    let (mut ramp_cycles, mut ramp_error) = (0, None);
    if !reason.drive_failed() && !record.is_empty() {
        last.copy_from_slice(&torque);
        let steps = plan.ramp_cycles.max(1);
        for s in 1..=steps {
            plan.hold.torque(&p, &p_prev, fs, &mut hold);
            let w = 1.0 - s as f64 / steps as f64;
            for i in 0..axes {
                torque[i] = hold[i] + (last[i] - hold[i]) * w;
            }
            let deadline = match plan.pacing {
                Pacing::Realtime => schedule.next_deadline(),
                Pacing::Lockstep => Instant::now() + plan.feedback_timeout,
            };
            match drive.cycle(&torque, deadline, &mut fb) {
                Ok(()) => ramp_cycles += 1,
                Err(e) => {
                    ramp_error = Some(e.to_string());
                    break;
                }
            }
            p_prev.copy_from_slice(&p);
            for i in 0..axes {
                p[i] = fb[i].position_rad - record.start_position_rad[i];
            }
            if plan.pacing == Pacing::Realtime {
                schedule.wait();
            }
        }
    }
    let end = RecordingEnd {
        complete: reason == StopReason::Complete,
        reason: reason.text(),
        cycle: stop_cycle,
    };
    MultiSweepOutcome {
        record,
        end,
        reason,
        counters: fb.iter().map(|f| f.counters).collect(),
        elapsed,
        overruns: schedule.overruns,
        ramp_cycles,
        ramp_error,
    }
}

/// The first limit this cycle's feedback breaks, if any.
fn limits(plan: &MultiSweepPlan, fb: &[Feedback], p: &[f64]) -> Option<StopReason> {
    let lost: u64 = fb.iter().map(|f| f.counters.lost).sum();
    if lost > plan.max_lost_tpdos {
        return Some(StopReason::FeedbackLost(format!(
            "{lost} feedback messages (TPDOs) lost on all axes together, budget {}",
            plan.max_lost_tpdos
        )));
    }
    for (i, f) in fb.iter().enumerate() {
        if f.velocity_rad_s.abs() > plan.max_speed_rad_s {
            return Some(StopReason::Overspeed {
                velocity_rad_s: f.velocity_rad_s,
                limit_rad_s: plan.max_speed_rad_s,
            });
        }
        if p[i].abs() > plan.max_excursion_rad {
            return Some(StopReason::DriveError(format!(
                "axis {}: motor {:.3} rad from its start position, limit {} rad: the holding loop lost the arm",
                i + 1,
                p[i],
                plan.max_excursion_rad
            )));
        }
    }
    None
}

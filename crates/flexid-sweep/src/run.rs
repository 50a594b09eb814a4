//! The sweep loop over a [`CyclicDrive`].

use super::plan::{Pacing, SweepPlan};
use super::rows::{RecordedRows, Row, RowSink};
use super::simulated::SimulatedFault;
use super::stale_fill::StaleFill;
use flexid_canopen::{Counters, CyclicDrive, DriveErrorKind, MasterError};
use flexid_core::excitation::ExcitationKind;
use flexid_core::recording::{CycleCounters, Recording, RecordingEnd, Sidecar};
use flexid_rt::clock::{self, InstantMap, MonoNs};
use flexid_rt::{RtGranted, RtSetup};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Why a sweep stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum StopReason {
    /// The planned excitation ran to its end.
    Complete,
    /// The drive reported a fault (EMCY, Fault state, left Operation enabled, NMT change).
    DriveFault(String),
    /// Feedback (TPDOs) lost beyond the budget, or missing in too many consecutive cycles.
    FeedbackLost(String),
    /// |velocity| above the limit.
    Overspeed {
        /// The velocity measured [rad/s].
        velocity_rad_s: f64,
        /// The limit [rad/s].
        limit_rad_s: f64,
    },
    /// The bus failed.
    BusError(String),
    /// Any other error of the drive interface.
    DriveError(String),
    /// The wall-time limit was reached.
    DurationLimit(Duration),
    /// Stopped from outside (Ctrl-C, SIGTERM).
    Interrupted,
}

impl StopReason {
    /// The text written to the sidecar's `end.reason`.
    pub fn text(&self) -> String {
        match self {
            StopReason::Complete => "excitation complete".into(),
            StopReason::DriveFault(e) => format!("drive fault: {e}"),
            StopReason::FeedbackLost(e) => format!("feedback lost: {e}"),
            StopReason::Overspeed {
                velocity_rad_s,
                limit_rad_s,
            } => format!(
                "speed limit: |velocity| {:.3} rad/s above the limit {limit_rad_s} rad/s",
                velocity_rad_s.abs()
            ),
            StopReason::BusError(e) => format!("bus error: {e}"),
            StopReason::DriveError(e) => format!("drive error: {e}"),
            StopReason::DurationLimit(d) => {
                format!("duration limit: {:.1} s reached", d.as_secs_f64())
            }
            StopReason::Interrupted => "interrupted (Ctrl-C / SIGTERM)".into(),
        }
    }

    /// Whether the drive itself failed (then the torque is not ramped: the drive is off
    /// or unreachable).
    pub fn drive_failed(&self) -> bool {
        matches!(
            self,
            StopReason::DriveFault(_)
                | StopReason::FeedbackLost(_)
                | StopReason::BusError(_)
                | StopReason::DriveError(_)
        )
    }

    /// Classify an error of drive type `D`: by the drive's own [`CyclicDrive::error_kind`]
    /// where it gives one (EtherCAT), by [`StopReason::of_error`] otherwise.
    pub fn of_drive_error<D: CyclicDrive>(e: &D::Error) -> Self {
        match D::error_kind(e) {
            Some(kind) => Self::of_kind(kind, e.to_string()),
            None => Self::of_error(e),
        }
    }

    /// The stop reason of a fieldbus-independent error kind, with the error's text.
    pub fn of_kind(kind: DriveErrorKind, text: String) -> Self {
        match kind {
            DriveErrorKind::DriveFault => StopReason::DriveFault(text),
            DriveErrorKind::FeedbackLost => StopReason::FeedbackLost(text),
            DriveErrorKind::Bus => StopReason::BusError(text),
            DriveErrorKind::Other => StopReason::DriveError(text),
        }
    }

    /// Classify an error of a [`CyclicDrive`].
    pub fn of_error(e: &(dyn std::error::Error + 'static)) -> Self {
        let text = e.to_string();
        if let Some(m) = e.downcast_ref::<MasterError>() {
            return match m {
                MasterError::Emergency { .. }
                | MasterError::Fault { .. }
                | MasterError::Disabled { .. }
                | MasterError::NmtStateChanged { .. } => StopReason::DriveFault(text),
                MasterError::TpdoLost { .. } => StopReason::FeedbackLost(text),
                MasterError::Bus { .. } | MasterError::ErrorFrameBurst { .. } => {
                    StopReason::BusError(text)
                }
                _ => StopReason::DriveError(text),
            };
        }
        if e.downcast_ref::<SimulatedFault>().is_some() {
            return StopReason::DriveFault(text);
        }
        StopReason::DriveError(text)
    }
}

/// Progress, reported after every period (multisine) or second (other excitations).
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    /// Cycles done.
    pub cycle: u64,
    /// Cycles planned.
    pub total: u64,
    /// Periods done and planned (multisine; 0 otherwise).
    pub periods_done: usize,
    /// Periods planned, transient ones included.
    pub periods_total: usize,
    /// Wall time since the first cycle.
    pub elapsed: Duration,
    /// Counters of the exchange.
    pub counters: Counters,
}

/// What a sweep measured and how it ended.
#[derive(Debug, Clone)]
pub struct SweepOutcome {
    /// The rows measured (all planned ones when complete); its sidecar holds the
    /// excitation, `end` and `cycle_counters` (the caller adds `drive`).
    pub recording: Recording,
    /// Why it stopped.
    pub reason: StopReason,
    /// The sidecar's `end`.
    pub end: RecordingEnd,
    /// Counters of the exchange at the end (ramp included).
    pub counters: Counters,
    /// Wall time of the recorded cycles.
    pub elapsed: Duration,
    /// Cycles started more than half a period behind the real-time schedule (the
    /// schedule restarted from each of them; 0 in lock-step).
    pub overruns: u64,
    /// Cycles run in the ramp to zero torque.
    pub ramp_cycles: usize,
    /// Why the ramp did not finish, if it did not.
    pub ramp_error: Option<String>,
    /// Rows recorded from a lost feedback (filled from their fresh neighbours).
    pub held_rows: u64,
    /// Frames placed by the drive's own cycle count ([`flexid_canopen::Feedback::drive_cycle`]).
    pub placement: GridPlacement,
}

/// Frames a drive that counts its own cycles saw outside their row's cycle (see
/// [`flexid_canopen::Feedback::drive_cycle`]); zero without such a drive.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GridPlacement {
    /// Frames that passed the drive one or more cycles after their row's: the rows between
    /// were recorded as held (the drive held its last torque).
    pub late_passes: u64,
    /// Frames that passed in the cycle of the row before: their set-point replaced that
    /// row's, which never acted.
    pub replaced_setpoints: u64,
}

impl SweepOutcome {
    /// True when the planned excitation ran to its end.
    pub fn complete(&self) -> bool {
        self.reason == StopReason::Complete
    }

    /// Recorded cycles per second of wall time.
    pub fn cycles_per_s(&self) -> f64 {
        self.recording.len() as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// The real-time schedule on the monotonic clock: absolute deadlines
/// ([`clock::sleep_until_ns`], `clock_nanosleep` with `TIMER_ABSTIME` on Linux), so a late
/// wake-up does not shift the following cycles. Cycle k's slot starts at `slot_ns` and its
/// feedback is due one period later. A master that falls more than half a period behind
/// (preempted, a loaded host) restarts the schedule from now, counted as an overrun:
/// firing the missed slots back to back would give the drive SYNCs closer than a period
/// and each cycle no time to answer. On a drive's grid ([`CyclicDrive::cycle_grid`]:
/// EtherCAT's SYNC0, the drive's own clock) the slots start on the grid, and an overrun
/// skips the slots the loop is behind by (to the grid point nearest to now, waited for
/// when ahead): the drive went through them holding its last torque, so the loop records
/// a held row for each ([`Schedule::take_skipped`]) and row k stays the drive's cycle k.
/// The grid is read once, when the sweep starts (a drive clock drifting against the
/// host's is not followed).
pub(crate) struct Schedule {
    map: InstantMap,
    period_ns: u64,
    slot_ns: MonoNs,
    /// The grid's phase: slots start at `phase_ns` modulo the period.
    grid_phase_ns: Option<u64>,
    pub(crate) overruns: u64,
    /// Grid slots skipped by overruns and not yet taken by the loop.
    skipped: u64,
}

impl Schedule {
    pub(crate) fn new(period: Duration) -> Self {
        Self {
            map: InstantMap::calibrate(),
            period_ns: (period.as_nanos() as u64).max(1),
            slot_ns: clock::now_ns(),
            grid_phase_ns: None,
            overruns: 0,
            skipped: 0,
        }
    }

    /// A schedule whose slots start on `grid` (see the type); the first slot is the grid
    /// point nearest to now (waited for when ahead). Without a grid, as [`Schedule::new`].
    pub(crate) fn on_grid(period: Duration, grid: Option<Instant>) -> Self {
        let mut s = Self::new(period);
        if let Some(grid) = grid {
            let (now_ns, now) = (clock::now_ns(), Instant::now());
            let grid_ns = if grid >= now {
                now_ns as i128 + (grid - now).as_nanos() as i128
            } else {
                now_ns as i128 - (now - grid).as_nanos() as i128
            };
            s.grid_phase_ns = Some(grid_ns.rem_euclid(i128::from(s.period_ns)) as u64);
            s.slot_ns = s.restart_at(now_ns);
        }
        s
    }

    /// The first slot's start on the grid: its point nearest to `now` (slept to when
    /// ahead); `now` without a grid.
    fn restart_at(&self, now: MonoNs) -> MonoNs {
        let Some(phase) = self.grid_phase_ns else {
            return now;
        };
        let p = self.period_ns;
        let mut slot = now - (now + p - phase % p) % p;
        if now - slot > p / 2 {
            slot += p;
            clock::sleep_until_ns(slot);
        }
        slot
    }

    /// The deadline of the cycle starting now (the end of its slot).
    #[inline]
    pub(crate) fn next_deadline(&mut self) -> Instant {
        let now = clock::now_ns();
        if now > self.slot_ns + self.period_ns / 2 {
            self.overruns += 1;
            if self.grid_phase_ns.is_some() {
                let p = self.period_ns;
                let behind = (now - self.slot_ns + p / 2) / p;
                self.slot_ns += behind * p;
                self.skipped += behind;
                clock::sleep_until_ns(self.slot_ns);
            } else {
                self.slot_ns = now;
            }
        }
        self.slot_ns += self.period_ns;
        self.map.instant(self.slot_ns)
    }

    /// Moves the schedule `slots` slots on (the drive's cycles a late frame let pass).
    pub(crate) fn skip(&mut self, slots: u64) {
        self.slot_ns += slots * self.period_ns;
    }

    /// The grid slots skipped since the last call (0 without a grid).
    pub(crate) fn take_skipped(&mut self) -> u64 {
        std::mem::take(&mut self.skipped)
    }

    /// Sleeps until the end of the current slot (absolute).
    #[inline]
    pub(crate) fn wait(&self) {
        clock::sleep_until_ns(self.slot_ns);
    }
}

/// The scheduling asked for a real-time sweep's cycle thread: `SCHED_FIFO` 80. Memory is
/// not locked (the loop does not allocate; the process goes on to the analysis after it).
pub fn realtime_setup() -> RtSetup {
    RtSetup {
        lock_memory: false,
        ..RtSetup::realtime(80)
    }
}

/// Runs [`run_sweep`] on a cycle thread of its own (joined before returning) with `setup`
/// applied when the OS permits; one line on stderr says what was granted, or what was
/// refused and what that means for the cycle. The calling thread's scheduling is left
/// alone (the analysis that follows runs at normal priority). Returns the outcome and
/// what was granted.
pub fn run_sweep_on_cycle_thread<D: CyclicDrive + Send>(
    drive: &mut D,
    plan: &SweepPlan,
    stop: &AtomicBool,
    progress: &mut (dyn FnMut(&Progress) + Send),
    setup: RtSetup,
) -> (SweepOutcome, RtGranted) {
    std::thread::scope(|s| {
        let h = s.spawn(move || {
            let granted = setup.apply();
            match (setup.fifo_priority, granted.fifo_priority) {
                (_, Some(p)) => {
                    eprintln!(
                        "flexid sweep: real-time cycle thread: SCHED_FIFO priority {p} granted"
                    )
                }
                (Some(_), None) => eprintln!(
                    "flexid sweep: real-time cycle thread at normal priority: {}; feedback \
                     may be late at kHz rates on a loaded machine",
                    granted.refused.join("; ")
                ),
                (None, None) => {}
            }
            (run_sweep(drive, plan, stop, progress), granted)
        });
        h.join().unwrap_or_else(|p| std::panic::resume_unwind(p))
    })
}

/// Runs `plan` on an enabled `drive`: one cycle per planned set-point, every one recorded
/// (into buffers allocated up front: the loop does not allocate), then the torque ramped
/// from its last value to zero over `plan.ramp_cycles` cycles unless the drive failed.
/// `stop` is polled every cycle. `progress` is called after every period (multisine) or
/// every second. The caller disables the drive afterwards.
pub fn run_sweep<D: CyclicDrive>(
    drive: &mut D,
    plan: &SweepPlan,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&Progress),
) -> SweepOutcome {
    let mut rows = RecordedRows::with_capacity(plan.torque_nm.len());
    let end = run_sweep_into(drive, plan, stop, progress, &mut rows);
    SweepOutcome {
        recording: rows.into_recording(plan.cycle_hz, end.sidecar.clone()),
        reason: end.reason,
        end: end.end,
        counters: end.counters,
        elapsed: end.elapsed,
        overruns: end.overruns,
        ramp_cycles: end.ramp_cycles,
        ramp_error: end.ramp_error,
        held_rows: end.held_rows,
        placement: end.placement,
    }
}

/// How a sweep of [`run_sweep_into`] ended (its rows are in the sink).
#[derive(Debug, Clone)]
pub struct SweepEnd {
    /// Rows recorded.
    pub rows: usize,
    /// Why it stopped.
    pub reason: StopReason,
    /// The sidecar's `end`.
    pub end: RecordingEnd,
    /// The recording's sidecar: excitation, rate, `end`, `cycle_counters` (the caller adds
    /// `drive`, `source`, `cycle_timing`).
    pub sidecar: Sidecar,
    /// Counters of the exchange at the end (ramp included).
    pub counters: Counters,
    /// Wall time of the recorded cycles.
    pub elapsed: Duration,
    /// Cycles started more than half a period behind the real-time schedule.
    pub overruns: u64,
    /// Cycles run in the ramp to zero torque.
    pub ramp_cycles: usize,
    /// Why the ramp did not finish, if it did not.
    pub ramp_error: Option<String>,
    /// Rows recorded from a lost feedback (filled from their fresh neighbours in the sink).
    pub held_rows: u64,
    /// Frames placed by the drive's own cycle count.
    pub placement: GridPlacement,
}

/// [`run_sweep`] with the rows going into `sink` (the daemon's sink streams them per
/// period to disk and to the live estimate, so they are stored once).
pub fn run_sweep_into<D: CyclicDrive>(
    drive: &mut D,
    plan: &SweepPlan,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&Progress),
    sink: &mut dyn RowSink,
) -> SweepEnd {
    let n = plan.torque_nm.len();
    let fs = plan.cycle_hz;
    let period = plan.period();
    let mut rows = 0usize;
    let info = &plan.excitation;
    let periodic = info.kind == ExcitationKind::Multisine && info.period_samples > 0;
    let report_every = if periodic {
        info.period_samples
    } else {
        (fs.round() as usize).max(1)
    };
    let periods_total = if periodic {
        info.periods + info.transient_periods
    } else {
        0
    };
    let base_lost = drive.counters().lost;
    // the rows recorded from a lost feedback: room for a run of the whole budget, up front
    let mut fill =
        StaleFill::with_capacity((plan.max_lost_tpdos.saturating_add(1)).min(n as u64) as usize);
    // a progress report (which publishes the rows so far) waits while a held row does
    let mut report_due = false;
    let t0 = Instant::now();
    let mut reason = StopReason::Complete;
    let mut stop_cycle = n as u64;
    let mut last_torque = 0.0;
    let mut schedule = match plan.pacing {
        Pacing::Realtime => Schedule::on_grid(period, drive.cycle_grid()),
        Pacing::Lockstep => Schedule::new(period),
    };
    // Cycles on a drive's own clock: its I/O delay goes into the recording.
    let on_grid = schedule.grid_phase_ns.is_some();

    // The last recorded row: the feedback a held row starts from (filled afterwards).
    let mut last_row = Row {
        torque_setpoint_nm: 0.0,
        position_rad: 0.0,
        velocity_rad_s: 0.0,
        torque_actual_nm: 0.0,
    };
    // The drive cycle of row 0 (drives that count their cycles, on the grid), and the
    // frames that passed the drive later or earlier than their row's cycle.
    let mut grid_base: Option<u64> = None;
    let (mut late_passes, mut replaced_setpoints) = (0u64, 0u64);
    let mut replaced_last = false;
    let mut k = 0;
    while k < n {
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
        let deadline = match plan.pacing {
            Pacing::Realtime => schedule.next_deadline(),
            Pacing::Lockstep => now + plan.feedback_timeout,
        };
        // Slots of a drive's grid this loop was too late for: the drive held the last
        // torque through them; a held row each (the feedback filled from the neighbours),
        // so that row k stays the drive's cycle k.
        let skipped = schedule.take_skipped().min((n - 1 - k) as u64);
        let held = Row {
            torque_setpoint_nm: last_torque,
            ..last_row
        };
        for _ in 0..skipped {
            fill.push(k, &held, false, sink);
            report_due |= (k + 1) % report_every == 0;
            k += 1;
        }
        rows += skipped as usize;
        let fb = match drive.cycle(plan.torque_nm[k], deadline) {
            Ok(fb) => fb,
            Err(e) => {
                reason = StopReason::of_drive_error::<D>(&e);
                stop_cycle = k as u64;
                break;
            }
        };
        // Where the feedback belongs on a drive that counts its own cycles (EtherCAT: the
        // SYNC0 pulse its inputs were latched at), and so which cycle this set-point acts
        // from; the timing alone cannot tell a frame that passed the drive in time and came
        // back late from one that passed a pulse late.
        let mut fresh = fb.fresh;
        let mut replaced_setpoint = false;
        if let (true, Some(m)) = (on_grid, fb.drive_cycle) {
            let first = *grid_base.get_or_insert(m.saturating_sub(k as u64));
            let row = m.saturating_sub(first);
            if row > k as u64 {
                // The frame passed `late` pulses after its own: the drive held the last
                // torque through them (held rows, the feedback filled from the neighbours),
                // and this set-point acts from the cycle after the one it read.
                let late = (row - k as u64).min((n - 1 - k) as u64);
                for _ in 0..late {
                    fill.push(k, &held, false, sink);
                    report_due |= (k + 1) % report_every == 0;
                    k += 1;
                }
                rows += late as usize;
                schedule.skip(late);
                late_passes += 1;
            } else if row + 1 == k as u64 && !replaced_last {
                // It passed in the cycle of the row before: that row's set-point never
                // acted, this one replaced it. (Once in a row, and only from the row just
                // before: a drive cycle that does not advance is no timing to place by, and
                // the rows go on as they come.)
                replaced_setpoint = fill.set_last_setpoint(k - 1, fb.torque_setpoint_nm, sink);
            }
            // The inputs of the drive's cycle, wherever in the cycle the frame came back.
            fresh = true;
        }
        replaced_last = replaced_setpoint;
        if replaced_setpoint {
            last_torque = fb.torque_setpoint_nm;
            replaced_setpoints += 1;
            if plan.pacing == Pacing::Realtime {
                schedule.wait();
            }
            // row k is still to come: the same plan sample goes out again
            continue;
        }
        last_row = Row {
            torque_setpoint_nm: fb.torque_setpoint_nm,
            position_rad: fb.position_rad,
            velocity_rad_s: fb.velocity_rad_s,
            torque_actual_nm: fb.torque_nm,
        };
        fill.push(k, &last_row, fresh, sink);
        rows += 1;
        last_torque = fb.torque_setpoint_nm;
        let lost = fb.counters.lost - base_lost;
        if lost > plan.max_lost_tpdos {
            reason = StopReason::FeedbackLost(format!(
                "{lost} feedback messages (TPDOs) lost, budget {}",
                plan.max_lost_tpdos
            ));
            stop_cycle = k as u64;
            break;
        }
        if fb.velocity_rad_s.abs() > plan.max_speed_rad_s {
            reason = StopReason::Overspeed {
                velocity_rad_s: fb.velocity_rad_s,
                limit_rad_s: plan.max_speed_rad_s,
            };
            stop_cycle = k as u64;
            break;
        }
        report_due |= (k + 1) % report_every == 0;
        if (report_due && !fill.waiting()) || k + 1 == n {
            report_due = false;
            progress(&Progress {
                cycle: (k + 1) as u64,
                total: n as u64,
                periods_done: if periodic {
                    (k + 1) / info.period_samples
                } else {
                    0
                },
                periods_total,
                elapsed: t0.elapsed(),
                counters: fb.counters,
            });
        }
        if plan.pacing == Pacing::Realtime {
            schedule.wait();
        }
        k += 1;
    }
    let elapsed = t0.elapsed();
    let overruns = schedule.overruns;

    // Ramp the torque to zero (not recorded) unless the drive is gone or faulted.
    let mut ramp_cycles = 0;
    let mut ramp_error = None;
    if !reason.drive_failed() {
        if plan.pacing == Pacing::Realtime {
            // a loop left early (speed limit, stop) has not waited out its last slot:
            // the ramp's first SYNC comes a period after the last one all the same
            schedule.wait();
        }
        let steps = plan.ramp_cycles.max(1);
        for i in 1..=steps {
            let t = last_torque * (1.0 - i as f64 / steps as f64);
            let deadline = match plan.pacing {
                Pacing::Realtime => schedule.next_deadline(),
                Pacing::Lockstep => Instant::now() + plan.feedback_timeout,
            };
            match drive.cycle(t, deadline) {
                Ok(_) => ramp_cycles += 1,
                Err(e) => {
                    ramp_error = Some(e.to_string());
                    break;
                }
            }
            if plan.pacing == Pacing::Realtime {
                schedule.wait();
            }
        }
    }

    let counters = drive.counters();
    let end = RecordingEnd {
        complete: reason == StopReason::Complete,
        reason: reason.text(),
        cycle: stop_cycle,
    };
    let sidecar = Sidecar {
        sample_rate_hz: Some(fs),
        excitation: Some(plan.excitation.clone()),
        io_delay_samples: Some(if on_grid {
            drive.grid_io_delay_cycles()
        } else {
            0
        }),
        ended_because: (!end.complete).then(|| end.reason.clone()),
        end: Some(end.clone()),
        cycle_counters: Some(CycleCounters {
            cycles: counters.cycles,
            missed: counters.missed,
            late: counters.late,
            lost: counters.lost,
            saturated: counters.saturated,
            malformed: counters.malformed,
            overruns,
            held_rows: fill.held(),
            late_passes,
            replaced_setpoints,
        }),
        ..Sidecar::default()
    };
    SweepEnd {
        rows,
        reason,
        end,
        sidecar,
        counters,
        elapsed,
        overruns,
        ramp_cycles,
        ramp_error,
        held_rows: fill.held(),
        placement: GridPlacement {
            late_passes,
            replaced_setpoints,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The distance of `ns` from the grid of `phase` (modulo `period`), either side, ns.
    fn off_grid(ns: u64, phase: u64, period: u64) -> u64 {
        let d = (ns + period - phase) % period;
        d.min(period - d)
    }

    #[test]
    fn a_schedule_on_a_drive_grid_starts_its_slots_on_it_and_counts_the_slots_an_overrun_skips() {
        let period = Duration::from_millis(1);
        let p = 1_000_000;
        let grid = Instant::now() + Duration::from_micros(2_300);
        let mut s = Schedule::on_grid(period, Some(grid));
        let phase = s.grid_phase_ns.expect("a grid");
        // The grid instant itself, on the monotonic clock, is on the grid (the two clocks
        // read a few hundred ns apart).
        let grid_ns = clock::now_ns() + (grid - Instant::now()).as_nanos() as u64;
        assert!(off_grid(grid_ns, phase, p) < 20_000, "{grid_ns} vs {phase}");
        assert_eq!(off_grid(s.slot_ns, phase, p), 0);
        let first = s.slot_ns;
        s.next_deadline();
        assert_eq!(s.slot_ns, first + p);
        // 2.7 periods behind: an overrun; three slots skipped (the loop records a held row
        // for each), the schedule still on the grid. A host that stalls between the sleep
        // and the call (this VM stalls up to 2 ms) makes it more: the slots skipped are
        // those the schedule moved on by.
        let behind_from = s.slot_ns;
        clock::sleep_until_ns(behind_from + 2_700_000);
        s.next_deadline();
        assert_eq!(s.overruns, 1);
        let skipped = s.take_skipped();
        assert!(skipped >= 3, "{skipped} slots skipped");
        assert_eq!(s.take_skipped(), 0, "taken once");
        assert_eq!(
            s.slot_ns,
            behind_from + (skipped + 1) * p,
            "the slot after the skipped ones runs, its deadline a period on"
        );
        assert_eq!(off_grid(s.slot_ns, phase, p), 0);
        // Without a grid, the first slot starts now.
        let t = clock::now_ns();
        let s = Schedule::on_grid(period, None);
        assert!(s.slot_ns >= t && s.slot_ns - t < 1_000_000);
        assert_eq!(s.grid_phase_ns, None);
    }
}

//! Rows placed by the drive's own cycle count (`Feedback::drive_cycle`, EtherCAT's DC
//! time): a frame that passes the drive a cycle late makes the drive hold its last torque,
//! and the recording must say so, whatever the frame's round trip told the loop.
//!
//! The drive here is a fake with the timing of a CiA 402 servo on SYNC0: pulses every
//! period on the wall clock; at pulse `p` it latches its state `x_p` into the inputs and
//! applies the set-point of the last frame that passed before it (held when none came);
//! `x_(p+1) = x_p + T_p` (a discrete integrator). Scripted frames pass one pulse late (the
//! fake sleeps past the pulse before "passing" them, as a frame stuck on the way does)
//! and come back fresh, inside the loop's deadline. The loop records row `r` as the inputs
//! of pulse `base + r` and the set-point that pulse `base + r + 1` applies (one cycle of
//! I/O delay, which the fake reports).

use flexid_canopen::{Counters, CyclicDrive, Feedback};
use flexid_core::excitation::MultisineDesign;
use flexid_sweep::{run_sweep, Pacing, StopReason, SweepPlan};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

const CYCLE_HZ: f64 = 1000.0;

struct Sync0Servo {
    /// Pulse 0 on the wall clock.
    origin: Instant,
    period: Duration,
    /// Whether to report `drive_cycle` (false: a bus that cannot say).
    reports_cycle: bool,
    /// A broken clock: this drive cycle reported for every frame.
    frozen_cycle: Option<u64>,
    /// Loop calls whose frame passes one pulse late.
    late_calls: Vec<u64>,
    calls: u64,
    /// The last pulse run, its state after the pulse's set-point acted, the set-point
    /// waiting for the next pulse.
    pulse: u64,
    state: f64,
    setpoint: f64,
    /// Per pulse: the state latched, the set-point applied.
    latched: Vec<f64>,
    applied: Vec<f64>,
    /// The pulse the first frame read.
    first_read: Option<u64>,
    counters: Counters,
}

impl Sync0Servo {
    fn new(reports_cycle: bool, late_calls: Vec<u64>) -> Self {
        Sync0Servo {
            origin: Instant::now(),
            period: Duration::from_secs_f64(1.0 / CYCLE_HZ),
            reports_cycle,
            frozen_cycle: None,
            late_calls,
            calls: 0,
            pulse: 0,
            state: 0.0,
            setpoint: 0.0,
            latched: vec![0.0],
            applied: vec![0.0],
            first_read: None,
            counters: Counters::default(),
        }
    }

    fn pulse_at(&self, t: Instant) -> u64 {
        (t.duration_since(self.origin).as_nanos() / self.period.as_nanos()) as u64
    }

    /// Runs the pulses up to `p`: each latches the state and applies the waiting set-point.
    fn run_pulses_to(&mut self, p: u64) {
        while self.pulse < p {
            self.state += self.applied[self.pulse as usize];
            self.pulse += 1;
            self.latched.push(self.state);
            self.applied.push(self.setpoint);
        }
    }
}

#[derive(Debug, thiserror::Error)]
#[error("never")]
struct Never;

impl CyclicDrive for Sync0Servo {
    type Error = Never;

    fn cycle(&mut self, torque_nm: f64, _deadline: Instant) -> Result<Feedback, Never> {
        let sync_time = Instant::now();
        let mut pass = self.pulse_at(sync_time);
        if self.late_calls.binary_search(&self.calls).is_ok() {
            // stuck on the way past the next pulse
            pass += 1;
            let at = self.origin + self.period * pass as u32 + self.period / 10;
            std::thread::sleep(at.saturating_duration_since(Instant::now()));
        }
        self.calls += 1;
        self.run_pulses_to(pass.max(self.pulse_at(Instant::now())));
        // passes in the interval after pulse `self.pulse`: reads its latch, leaves its
        // set-point for the next pulse
        let read = self.pulse;
        self.first_read.get_or_insert(read);
        self.setpoint = torque_nm;
        self.counters.cycles += 1;
        Ok(Feedback {
            cycle: self.calls - 1,
            sync_time,
            statusword: 0x0027,
            state: None,
            position_rad: self.latched[read as usize],
            velocity_rad_s: 0.0,
            torque_nm: self.applied[read as usize],
            torque_setpoint_nm: torque_nm,
            saturated: false,
            fresh: true,
            drive_cycle: self.frozen_cycle.or(self.reports_cycle.then_some(read)),
            counters: self.counters,
        })
    }

    fn cycle_period(&self) -> Duration {
        self.period
    }

    fn rated_torque_nm(&self) -> f64 {
        1.0
    }

    fn counters(&self) -> Counters {
        self.counters
    }

    /// Slots start a fifth of a period after each pulse.
    fn cycle_grid(&self) -> Option<Instant> {
        Some(self.origin + self.period / 5)
    }

    fn grid_io_delay_cycles(&self) -> u32 {
        1
    }
}

fn plan() -> SweepPlan {
    let mut d = MultisineDesign::new(CYCLE_HZ, 200, [5.0, 200.0], 0.4, 1.0);
    d.crest_iterations = 5;
    let ms = d.generate().expect("multisine");
    SweepPlan::new(CYCLE_HZ, ms.repeat(3), ms.info(2, 1), Pacing::Realtime)
}

/// Rows whose torque is not the one the drive applied one pulse later, and rows whose
/// position is not the state latched at their pulse, against the drive's own history.
fn compare(servo: &Sync0Servo, torque: &[f64], position: &[f64], base: u64) -> (usize, usize) {
    let (mut wrong_torque, mut wrong_position) = (0, 0);
    for r in 0..torque.len() {
        let p = base as usize + r;
        if p + 1 >= servo.applied.len() {
            break;
        }
        wrong_torque += usize::from(torque[r] != servo.applied[p + 1]);
        wrong_position += usize::from(position[r] != servo.latched[p]);
    }
    (wrong_torque, wrong_position)
}

/// Rows of wrong torque, of wrong position, late passes placed, held rows.
fn sweep(reports_cycle: bool) -> (usize, usize, u64, u64) {
    let plan = plan();
    let late: Vec<u64> = (1..6).map(|i| i * 97).collect();
    let mut servo = Sync0Servo::new(reports_cycle, late.clone());
    let stop = AtomicBool::new(false);
    let out = run_sweep(&mut servo, &plan, &stop, &mut |_| {});
    assert_eq!(out.reason, StopReason::Complete, "{:?}", out.reason);
    let rec = &out.recording;
    assert_eq!(rec.sidecar.io_delay_samples, Some(1));
    // the recording says so itself
    let counters = rec.sidecar.cycle_counters.as_ref().expect("cycle counters");
    assert_eq!(counters.held_rows, out.held_rows);
    assert_eq!(counters.late_passes, out.placement.late_passes);
    assert_eq!(
        counters.replaced_setpoints,
        out.placement.replaced_setpoints
    );
    assert_eq!(rec.len(), plan.torque_nm.len());
    let base = servo.first_read.expect("a frame");
    let (wrong, positions) = compare(
        &servo,
        &rec.torque_cmd_nm,
        rec.position_rad.as_ref().expect("positions"),
        base,
    );
    eprintln!(
        "drive_cycle reported: {reports_cycle}: {} late frames, rows whose torque is not the \
         applied one: {wrong}, rows whose position is not their pulse's: {positions}, late \
         passes placed {}, held rows {}",
        late.len(),
        out.placement.late_passes,
        out.held_rows
    );
    (wrong, positions, out.placement.late_passes, out.held_rows)
}

#[test]
fn a_frame_that_passes_the_drive_late_is_recorded_as_the_held_torque_it_caused() {
    // Scheduling stalls of this host add late passes of their own: they must be placed
    // too, so nothing here depends on there being exactly five.
    let (wrong, positions, placed, held) = sweep(true);
    assert_eq!(wrong, 0, "every row's torque is the one the drive applied");
    assert!(
        placed >= 5,
        "the five scripted late frames placed: {placed}"
    );
    // every row read at its own pulse, but the held ones (interpolated from their
    // neighbours: the drive's inputs of that pulse were never read)
    assert!(held >= placed);
    assert!(
        positions as u64 <= held,
        "{positions} positions wrong, {held} held rows"
    );
}

#[test]
fn without_the_drive_cycle_the_late_frames_leave_wrong_torques_in_the_recording() {
    // The same sweep on a bus that does not say where its frames passed: the loop's
    // timing sees nothing late (every frame came back in its slot), so rows of torque the
    // drive never applied stay in the recording. This is what the drive cycle fixes.
    let (wrong, _, placed, _) = sweep(false);
    assert_eq!(placed, 0);
    assert!(wrong >= 5, "{wrong} rows wrong");
}

#[test]
fn a_drive_cycle_that_never_advances_does_not_hold_the_sweep_back() {
    // Every frame reports the same cycle: after one replaced set-point the rows go on as
    // they come (without that rule the loop would resend one set-point until the
    // duration limit).
    let plan = plan();
    let mut servo = Sync0Servo::new(true, Vec::new());
    servo.frozen_cycle = Some(7);
    let stop = AtomicBool::new(false);
    let out = run_sweep(&mut servo, &plan, &stop, &mut |_| {});
    assert_eq!(out.reason, StopReason::Complete, "{:?}", out.reason);
    assert_eq!(out.recording.len(), plan.torque_nm.len());
    let planned_s = plan.torque_nm.len() as f64 / CYCLE_HZ;
    assert!(
        out.elapsed.as_secs_f64() < 1.5 * planned_s + 0.5,
        "{:?} for {planned_s} s planned",
        out.elapsed
    );
    assert_eq!(
        out.placement.replaced_setpoints, 1,
        "only the row after the frozen one"
    );
}

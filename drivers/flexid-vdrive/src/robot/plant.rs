//! One coupled multi-axis plant shared by the drives of a robot: the linearised flexible
//! manipulator at one pose ([`SampledPose`], exact zero-order hold), stepped once per cycle
//! with every axis's torque.
//!
//! Each drive owns a [`CoupledAxis`] (its [`Physics`]): `sample` reads its motor from the
//! shared state; `step` queues its torque for the coming cycle. The plant advances one
//! cycle as soon as every axis has queued one, so a SYNC seen by all drives advances it
//! exactly once, whatever order the drives handle it in, and every drive samples the state
//! before that cycle's torques act (the drive's timing convention). In real-time clock
//! mode a drive may step several cycles on one SYNC; the queue holds them until the
//! others catch up. Should one axis run [`QUEUE`] cycles ahead (a drive that stopped
//! seeing SYNCs), the plant advances with the others' last torques held.

use std::sync::{Arc, Mutex, MutexGuard};

use flexid_core::manipulator::sampled::SampledPose;
use flexid_core::manipulator::{Flexibilities, ManipulatorError, RigidPose};

use crate::physics::{AxisSample, Physics, PhysicsError};

/// Cycles one axis may run ahead of the slowest before the plant advances without it.
pub const QUEUE: usize = 8;

/// The shared state of a robot's plant. Build it with [`RobotPlant::new`], then hand
/// [`RobotPlant::axis`] to each drive.
#[derive(Debug)]
pub struct RobotPlant {
    pose: RigidPose,
    theta: Flexibilities,
    cycle_hz: f64,
    sampled: SampledPose,
    /// State `[q; v]` (arm side, deviations from the pose).
    x: Vec<f64>,
    /// Per axis: queued torques [N m, motor side] and how many.
    queued: Vec<([f64; QUEUE], usize)>,
    /// The torques of the last cycle stepped (held by an axis that has queued none).
    held: Vec<f64>,
    /// Scratch: the torques of the cycle being stepped.
    u: Vec<f64>,
    /// Cycles stepped.
    cycles: u64,
}

/// A shared handle on a [`RobotPlant`].
pub type SharedPlant = Arc<Mutex<RobotPlant>>;

impl RobotPlant {
    /// The plant of `pose` with springs `theta`, at rest, stepping at `cycle_hz` [Hz].
    pub fn new(
        pose: RigidPose,
        theta: Flexibilities,
        cycle_hz: f64,
    ) -> Result<SharedPlant, ManipulatorError> {
        let sampled = SampledPose::new(&pose, &theta, cycle_hz)?;
        let axes = sampled.axes();
        Ok(Arc::new(Mutex::new(RobotPlant {
            x: vec![0.0; sampled.states()],
            queued: vec![([0.0; QUEUE], 0); axes],
            held: vec![0.0; axes],
            u: vec![0.0; axes],
            cycles: 0,
            pose,
            theta,
            cycle_hz,
            sampled,
        })))
    }

    /// Axis `axis`'s physics on the shared plant.
    pub fn axis(plant: &SharedPlant, axis: usize) -> CoupledAxis {
        CoupledAxis {
            plant: Arc::clone(plant),
            axis,
        }
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.sampled.axes()
    }

    /// Cycles stepped since the start.
    pub fn cycles(&self) -> u64 {
        self.cycles
    }

    /// The sampled plant (its exact FRF matrix is what a measurement converges to).
    pub fn sampled(&self) -> &SampledPose {
        &self.sampled
    }

    /// Motor `axis`'s position [rad] and velocity [rad/s] (motor side).
    fn motor(&self, axis: usize) -> (f64, f64) {
        let (coord, ratio) = self.sampled.motor(axis);
        let n = self.sampled.states() / 2;
        (ratio * self.x[coord], ratio * self.x[n + coord])
    }

    /// Queues axis `axis`'s torque for the coming cycle; steps every cycle all axes have
    /// queued.
    fn queue(&mut self, axis: usize, torque_nm: f64) {
        if self.queued[axis].1 == QUEUE {
            // this axis is QUEUE cycles ahead: the others hold their torques
            self.advance(true);
        }
        let (q, n) = &mut self.queued[axis];
        q[*n] = torque_nm;
        *n += 1;
        while self.queued.iter().all(|(_, n)| *n > 0) {
            self.advance(false);
        }
    }

    /// One cycle with the first queued torque of every axis (or its held one when
    /// `hold_missing` and it has none).
    fn advance(&mut self, hold_missing: bool) {
        for (i, (q, n)) in self.queued.iter_mut().enumerate() {
            if *n > 0 {
                self.u[i] = q[0];
                q.copy_within(1..*n, 0);
                *n -= 1;
            } else {
                debug_assert!(hold_missing);
                self.u[i] = self.held[i];
            }
        }
        self.sampled.step(&mut self.x, &self.u);
        self.held.copy_from_slice(&self.u);
        self.cycles += 1;
    }

    /// Re-discretises at `cycle_hz` (the master's 0x1006), keeping the state.
    fn set_cycle_hz(&mut self, cycle_hz: f64) -> Result<(), ManipulatorError> {
        if cycle_hz != self.cycle_hz {
            self.sampled = SampledPose::new(&self.pose, &self.theta, cycle_hz)?;
            self.cycle_hz = cycle_hz;
        }
        Ok(())
    }
}

/// One axis of a [`RobotPlant`]: the [`Physics`] of one drive of the robot.
#[derive(Debug, Clone)]
pub struct CoupledAxis {
    plant: SharedPlant,
    axis: usize,
}

impl CoupledAxis {
    fn lock(&self) -> MutexGuard<'_, RobotPlant> {
        // a drive that panicked while holding the lock left a consistent state (every
        // update is a whole cycle): go on with it
        self.plant.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The axis index.
    pub fn axis(&self) -> usize {
        self.axis
    }
}

impl Physics for CoupledAxis {
    fn sample(&mut self) -> AxisSample {
        let p = self.lock();
        let (position_rad, velocity_rad_s) = p.motor(self.axis);
        AxisSample {
            time_s: p.cycles as f64 / p.cycle_hz,
            position_rad,
            velocity_rad_s,
            torque_nm: p.held[self.axis],
            load_position_rad: position_rad,
        }
    }

    fn step(&mut self, torque_nm: f64) {
        let axis = self.axis;
        self.lock().queue(axis, torque_nm);
    }

    fn cycle_adjustable(&self) -> bool {
        true
    }

    fn set_cycle_hz(&mut self, cycle_hz: f64) -> Result<(), PhysicsError> {
        if !(cycle_hz.is_finite() && cycle_hz > 0.0) {
            return Err(PhysicsError::CycleFixed { cycle_hz });
        }
        self.lock()
            .set_cycle_hz(cycle_hz)
            .map_err(|_| PhysicsError::CycleFixed { cycle_hz })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flexid_core::manipulator::reference;

    fn plant() -> (SharedPlant, SampledPose, usize) {
        let r = reference::robot();
        let (_, q) = r.poses_of(flexid_core::manipulator::PoseRole::Identification)[0].clone();
        let pose = r.pose(&q).unwrap();
        let sampled = SampledPose::new(&pose, &r.nominal, 1000.0).unwrap();
        let axes = sampled.axes();
        (
            RobotPlant::new(pose, r.nominal.clone(), 1000.0).unwrap(),
            sampled,
            axes,
        )
    }

    /// Six axes stepping in any order, several cycles ahead of each other, give the same
    /// motor trajectories as the sampled plant stepped with all torques at once.
    #[test]
    fn axes_in_any_order_step_the_one_plant() {
        let (shared, mut reference, axes) = plant();
        let mut drives: Vec<CoupledAxis> =
            (0..axes).map(|i| RobotPlant::axis(&shared, i)).collect();
        let mut x = vec![0.0; reference.states()];
        let mut p = vec![0.0; axes];
        let torque = |k: usize, i: usize| 0.1 * ((k * (i + 3)) as f64 * 0.01).sin();
        let mut k = 0;
        while k < 600 {
            // a round: axis order rotates; every third round axis 0 steps 3 cycles first
            let burst = if (k / 3) % 3 == 0 { 3 } else { 1 };
            // every drive samples the state before this round's torques act
            reference.motor_positions(&x, &mut p);
            for (i, d) in drives.iter_mut().enumerate() {
                let s = d.sample();
                assert!((s.position_rad - p[i]).abs() <= 1e-15 + 1e-12 * p[i].abs());
            }
            for c in 0..burst {
                let u: Vec<f64> = (0..axes).map(|i| torque(k + c, i)).collect();
                reference.step(&mut x, &u);
            }
            for j in 0..axes {
                let i = (j + k) % axes;
                for c in 0..burst {
                    drives[i].step(torque(k + c, i));
                }
            }
            k += burst;
        }
        assert_eq!(shared.lock().unwrap().cycles(), k as u64);
        reference.motor_positions(&x, &mut p);
        for i in 0..axes {
            let s = drives[i].sample();
            assert!(
                (s.position_rad - p[i]).abs() <= 1e-12 * p[i].abs().max(1e-9),
                "{i}"
            );
            assert!(p[i].abs() > 1e-9, "the torques moved axis {i}");
        }
    }

    /// An axis that runs QUEUE cycles ahead does not stall the plant: it advances with the
    /// others' torques held.
    #[test]
    fn a_runaway_axis_advances_with_the_others_held() {
        let (shared, _, _) = plant();
        let mut a0 = RobotPlant::axis(&shared, 0);
        for _ in 0..QUEUE + 5 {
            a0.step(0.1);
        }
        assert_eq!(shared.lock().unwrap().cycles(), 5);
        assert!(a0.sample().position_rad != 0.0);
    }
}

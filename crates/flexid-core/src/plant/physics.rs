//! The physics behind a drive: a trait a drive (the simulated CiA 402 drive on the bus,
//! or the sweep's CAN-free simulated drive) samples and steps once per cycle, its exact
//! linear implementation for an n-mass chain ([`LinearChain`]), the nonlinear plant
//! ([`PlantSim`], every effect of a plant file's `[effects]` section) and a white
//! disturbance torque on top of any of them ([`TorqueNoise`]).

use super::{AxisSample, PlantSim, PlantSpec};
use crate::model::{Chain, ModelError, StateSpace};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A physics model the drive advances in whole cycles under zero-order hold.
///
/// Implementations must not allocate in `sample` or `step` (they run every cycle).
pub trait Physics: Send {
    /// The state at the current cycle instant.
    fn sample(&mut self) -> AxisSample;
    /// Hold `torque_nm` [N m] on the motor for one cycle and advance to the next instant.
    fn step(&mut self, torque_nm: f64);
    /// Whether [`Physics::set_cycle_hz`] is supported (the master may then write 0x1006).
    fn cycle_adjustable(&self) -> bool {
        false
    }
    /// Changes the cycle rate [Hz] (the master's 0x1006), keeping the state where the
    /// model can. Called at configuration time, never per cycle (may allocate).
    fn set_cycle_hz(&mut self, cycle_hz: f64) -> Result<(), PhysicsError> {
        Err(PhysicsError::CycleFixed { cycle_hz })
    }
}

impl<P: Physics + ?Sized> Physics for Box<P> {
    fn sample(&mut self) -> AxisSample {
        (**self).sample()
    }
    fn step(&mut self, torque_nm: f64) {
        (**self).step(torque_nm)
    }
    fn cycle_adjustable(&self) -> bool {
        (**self).cycle_adjustable()
    }
    fn set_cycle_hz(&mut self, cycle_hz: f64) -> Result<(), PhysicsError> {
        (**self).set_cycle_hz(cycle_hz)
    }
}

/// The nonlinear plant (current loop, friction, backlash, ..., noise).
impl Physics for PlantSim {
    fn sample(&mut self) -> AxisSample {
        PlantSim::sample(self)
    }
    fn step(&mut self, torque_nm: f64) {
        PlantSim::step(self, torque_nm)
    }
}

/// [`PlantSim`] with what it needs to be rebuilt at another cycle rate (the
/// master's 0x1006). A rebuild restarts the plant at its initial state (configuration time).
pub struct PlantSimPhysics {
    sim: PlantSim,
    spec: PlantSpec,
    substeps: u32,
    seed: u64,
    initial_velocity_rad_s: f64,
}

impl PlantSimPhysics {
    /// The plant of `spec` at `cycle_hz`, `substeps` per cycle, noise `seed`, every body
    /// starting at `initial_velocity_rad_s`.
    pub fn new(
        spec: PlantSpec,
        cycle_hz: f64,
        substeps: u32,
        seed: u64,
        initial_velocity_rad_s: f64,
    ) -> Result<Self, PhysicsError> {
        let mut sim = PlantSim::new(&spec, cycle_hz, substeps, seed)
            .map_err(|e| PhysicsError::Plant(e.to_string()))?;
        sim.set_initial_velocity(initial_velocity_rad_s);
        Ok(Self {
            sim,
            spec,
            substeps,
            seed,
            initial_velocity_rad_s,
        })
    }
}

impl Physics for PlantSimPhysics {
    fn sample(&mut self) -> AxisSample {
        Physics::sample(&mut self.sim)
    }
    fn step(&mut self, torque_nm: f64) {
        self.sim.step(torque_nm)
    }
    fn cycle_adjustable(&self) -> bool {
        true
    }
    fn set_cycle_hz(&mut self, cycle_hz: f64) -> Result<(), PhysicsError> {
        *self = Self::new(
            self.spec.clone(),
            cycle_hz,
            self.substeps,
            self.seed,
            self.initial_velocity_rad_s,
        )?;
        Ok(())
    }
}

/// A white Gaussian disturbance torque added to every cycle's torque before it acts on
/// `inner` (seeded: the same seed gives the same disturbance). The sample's torque stays
/// the commanded one's, as the drive's current would.
pub struct TorqueNoise<P> {
    inner: P,
    rms_nm: f64,
    rng: rand::rngs::StdRng,
    unit: Normal<f64>,
}

impl<P: Physics> TorqueNoise<P> {
    /// `inner` disturbed by a torque of RMS `rms_nm` [N m] (0: none), noise `seed`.
    pub fn new(inner: P, rms_nm: f64, seed: u64) -> Self {
        TorqueNoise {
            inner,
            rms_nm: if rms_nm.is_finite() {
                rms_nm.max(0.0)
            } else {
                0.0
            },
            rng: rand::rngs::StdRng::seed_from_u64(seed),
            unit: Normal::new(0.0, 1.0).expect("unit normal"),
        }
    }
}

impl<P: Physics> Physics for TorqueNoise<P> {
    fn sample(&mut self) -> AxisSample {
        self.inner.sample()
    }
    fn step(&mut self, torque_nm: f64) {
        let w = if self.rms_nm > 0.0 {
            self.rms_nm * self.unit.sample(&mut self.rng)
        } else {
            0.0
        };
        self.inner.step(torque_nm + w)
    }
}

/// Errors of the physics layer.
#[derive(Debug, thiserror::Error)]
pub enum PhysicsError {
    /// The chain's parameters are invalid.
    #[error("chain: {0}")]
    Chain(#[from] ModelError),
    /// The cycle rate is not a positive finite number.
    #[error("cycle rate {cycle_hz} Hz must be positive and finite")]
    CycleRate {
        /// The rejected rate [Hz].
        cycle_hz: f64,
    },
    /// The model cannot change its cycle rate.
    #[error("this plant model cannot change its cycle rate (to {cycle_hz} Hz)")]
    CycleFixed {
        /// The requested rate [Hz].
        cycle_hz: f64,
    },
    /// The nonlinear plant could not be built.
    #[error("plant: {0}")]
    Plant(String),
}

/// An n-mass chain advanced exactly under ZOH, `x[k+1] = Ad x[k] + Bd T[k]`, with the
/// discretisation of [`crate::model::StateSpace::discretize`] (the same one
/// `crate::sim::simulate_position` uses). State `[theta_1..theta_n, omega_1..omega_n]`.
#[derive(Debug, Clone)]
pub struct LinearChain {
    chain: Chain,
    n: usize,
    ts: f64,
    /// `Ad`, row-major, `2n x 2n`.
    ad: Vec<f64>,
    /// `Bd`, `2n`.
    bd: Vec<f64>,
    x: Vec<f64>,
    next: Vec<f64>,
    cycles: u64,
    last_torque_nm: f64,
}

impl LinearChain {
    /// The chain at rest, stepped at `cycle_hz` [Hz].
    pub fn new(chain: &Chain, cycle_hz: f64) -> Result<Self, PhysicsError> {
        chain.validate()?;
        if !(cycle_hz.is_finite() && cycle_hz > 0.0) {
            return Err(PhysicsError::CycleRate { cycle_hz });
        }
        let ts = 1.0 / cycle_hz;
        let d = StateSpace::of(chain).discretize(ts);
        let n = chain.masses();
        let m = 2 * n;
        let mut ad = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                ad[i * m + j] = d.ad[(i, j)];
            }
        }
        Ok(Self {
            chain: chain.clone(),
            n,
            ts,
            ad,
            bd: d.bd.iter().copied().collect(),
            x: vec![0.0; m],
            next: vec![0.0; m],
            cycles: 0,
            last_torque_nm: 0.0,
        })
    }

    /// The cycle period [s].
    pub fn cycle_s(&self) -> f64 {
        self.ts
    }

    /// Sets every body's velocity to `rad_s` [rad/s] (a drifting start).
    pub fn set_velocity(&mut self, rad_s: f64) {
        let n = self.n;
        for v in &mut self.x[n..] {
            *v = rad_s;
        }
    }
}

impl Physics for LinearChain {
    fn sample(&mut self) -> AxisSample {
        AxisSample {
            time_s: self.cycles as f64 * self.ts,
            position_rad: self.x[0],
            velocity_rad_s: self.x[self.n],
            torque_nm: self.last_torque_nm,
            load_position_rad: self.x[self.n - 1],
        }
    }

    fn cycle_adjustable(&self) -> bool {
        true
    }

    /// Re-discretises at `cycle_hz`, keeping the state (angles, velocities) and the time.
    fn set_cycle_hz(&mut self, cycle_hz: f64) -> Result<(), PhysicsError> {
        let time_s = self.cycles as f64 * self.ts;
        let mut fresh = LinearChain::new(&self.chain, cycle_hz)?;
        fresh.x.copy_from_slice(&self.x);
        fresh.cycles = (time_s / fresh.ts).round() as u64;
        fresh.last_torque_nm = self.last_torque_nm;
        *self = fresh;
        Ok(())
    }

    fn step(&mut self, torque_nm: f64) {
        let m = 2 * self.n;
        // Same summation order as crate::sim::simulate_position (bit-identical results).
        for (i, nx) in self.next.iter_mut().enumerate() {
            let mut acc = self.bd[i] * torque_nm;
            for (a, xj) in self.ad[i * m..(i + 1) * m].iter().zip(&self.x) {
                acc += a * xj;
            }
            *nx = acc;
        }
        std::mem::swap(&mut self.x, &mut self.next);
        self.cycles += 1;
        self.last_torque_nm = torque_nm;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_flexid_sim_exactly() {
        let chain =
            Chain::new(vec![2e-3, 4e-3, 9e-3], vec![600.0, 9000.0], vec![0.05, 0.3]).unwrap();
        let torque: Vec<f64> = (0..500).map(|k| ((k as f64) * 0.37).sin() * 0.3).collect();
        let opts = crate::sim::SimOptions {
            sample_rate_hz: 2000.0,
            ..Default::default()
        };
        let want = crate::sim::simulate_position(&chain, &torque, &opts).unwrap();
        let mut p = LinearChain::new(&chain, 2000.0).unwrap();
        for (k, &t) in torque.iter().enumerate() {
            assert_eq!(p.sample().position_rad, want[k], "sample {k}");
            p.step(t);
        }
    }

    #[test]
    fn rejects_bad_rate() {
        let chain = Chain::new(vec![1e-3], vec![], vec![]).unwrap();
        assert!(matches!(
            LinearChain::new(&chain, 0.0),
            Err(PhysicsError::CycleRate { .. })
        ));
    }
}

//! A CAN-free drive: the exact ZOH simulation of a chain behind [`CyclicDrive`], for tests
//! of the sweep logic and for the demo when no bus can be used.

use flexid_canopen::cia402::State;
use flexid_canopen::{Counters, CyclicDrive, Feedback};
use flexid_core::model::{Chain, ModelError, StateSpace};
use std::time::{Duration, Instant};

/// A fault injected into a [`SimulatedDrive`] (an EMCY as a real drive would send).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("simulated drive: EMCY {code:#06x} ({text}) at cycle {cycle}")]
pub struct SimulatedFault {
    /// The cycle at which it happened.
    pub cycle: u64,
    /// The emergency error code.
    pub code: u16,
    /// Its class.
    pub text: &'static str,
}

/// An enabled drive in CST whose axis is `chain`, simulated exactly (zero-order hold, as
/// `flexid_core::sim`): the feedback of cycle k is the state before torque k acts; the torque
/// actual is the one held during the previous cycle. No allocation per cycle.
#[derive(Debug, Clone)]
pub struct SimulatedDrive {
    m: usize,
    n: usize,
    ad: Vec<f64>,
    bd: Vec<f64>,
    x: Vec<f64>,
    next: Vec<f64>,
    period: Duration,
    rated_torque_nm: f64,
    increments_per_rev: Option<f64>,
    last_torque: f64,
    counters: Counters,
    fault_at: Option<u64>,
}

impl SimulatedDrive {
    /// A drive on `chain` cycling at `cycle_hz`, at rest, rated torque 1 N m, exact
    /// position (no encoder quantisation).
    pub fn new(chain: &Chain, cycle_hz: f64) -> Result<Self, ModelError> {
        chain.validate()?;
        if !(cycle_hz.is_finite() && cycle_hz > 0.0) {
            return Err(ModelError::SampleRate { fs_hz: cycle_hz });
        }
        let n = chain.masses();
        let m = 2 * n;
        let d = StateSpace::of(chain).discretize(1.0 / cycle_hz);
        let mut ad = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                ad[i * m + j] = d.ad[(i, j)];
            }
        }
        Ok(SimulatedDrive {
            m,
            n,
            ad,
            bd: d.bd.iter().copied().collect(),
            x: vec![0.0; m],
            next: vec![0.0; m],
            period: Duration::from_secs_f64(1.0 / cycle_hz),
            rated_torque_nm: 1.0,
            increments_per_rev: None,
            last_torque: 0.0,
            counters: Counters::default(),
            fault_at: None,
        })
    }

    /// Quantise the position as an encoder with this many increments per revolution.
    pub fn with_encoder(mut self, increments_per_rev: f64) -> Self {
        self.increments_per_rev = Some(increments_per_rev);
        self
    }

    /// Fail with an EMCY (0x8400, velocity) at cycle `cycle` (0-based): that cycle
    /// returns the error, as a CANopen drive's EMCY does.
    pub fn fault_at(mut self, cycle: u64) -> Self {
        self.fault_at = Some(cycle);
        self
    }
}

impl CyclicDrive for SimulatedDrive {
    type Error = SimulatedFault;

    fn cycle(&mut self, torque_nm: f64, _deadline: Instant) -> Result<Feedback, SimulatedFault> {
        let cycle = self.counters.cycles;
        if self.fault_at == Some(cycle) {
            return Err(SimulatedFault {
                cycle,
                code: 0x8400,
                text: "velocity speed controller (simulated)",
            });
        }
        let sync_time = Instant::now();
        let mut position = self.x[0];
        if let Some(inc) = self.increments_per_rev {
            let q = std::f64::consts::TAU / inc;
            position = (position / q).round() * q;
        }
        let velocity = self.x[self.n];
        let m = self.m;
        for i in 0..m {
            let row = &self.ad[i * m..(i + 1) * m];
            let mut acc = self.bd[i] * torque_nm;
            for (a, xj) in row.iter().zip(&self.x) {
                acc += a * xj;
            }
            self.next[i] = acc;
        }
        std::mem::swap(&mut self.x, &mut self.next);
        let actual = self.last_torque;
        self.last_torque = torque_nm;
        self.counters.cycles += 1;
        Ok(Feedback {
            cycle,
            sync_time,
            statusword: 0x0027,
            state: Some(State::OperationEnabled),
            position_rad: position,
            velocity_rad_s: velocity,
            torque_nm: actual,
            torque_setpoint_nm: torque_nm,
            saturated: false,
            fresh: true,
            counters: self.counters,
        })
    }

    fn cycle_period(&self) -> Duration {
        self.period
    }

    fn rated_torque_nm(&self) -> f64 {
        self.rated_torque_nm
    }

    fn counters(&self) -> Counters {
        self.counters
    }
}

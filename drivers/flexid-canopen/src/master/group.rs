//! Several CiA 402 drives on one bus, cycled together: every cycle each drive's RPDO1
//! (its torque set-point) goes out, then one SYNC for all, then every drive's TPDOs are
//! collected (the multi-axis measurement: all set-points act in the same cycle).
//!
//! Each drive keeps its own bus handle (its own receive queue) and its own exchange
//! bookkeeping ([`super::exchange::Exchange`]); the group only orders the phases. The
//! drives are enabled and disabled one after the other (their CiA 402 walks send their
//! own SYNCs; the drives already enabled hold torque 0 meanwhile).

use std::time::{Duration, Instant};

use flexid_can::CanBus;

use super::cyclic::Mode;
use super::{Configured, Drive, Enabled, MasterError};
use crate::cia402::Controlword;
use crate::drive::{Counters, Feedback, MultiAxisDrive};
use crate::scaling::TorqueSetpoint;

/// Enabled drives cycled with one SYNC.
#[derive(Debug)]
pub struct DriveGroup<B: CanBus> {
    drives: Vec<Drive<B, Enabled>>,
    /// Scratch per drive: this cycle's set-point, cycle number, freshness.
    setpoints: Vec<TorqueSetpoint>,
    cycles: Vec<u64>,
    fresh: Vec<bool>,
}

impl<B: CanBus> DriveGroup<B> {
    /// Enables `drives` in order (they must share one bus and one cycle period). On a
    /// failure the drives already enabled are disabled again and the error names the
    /// drive that failed.
    pub fn enable(drives: Vec<Drive<B, Configured>>) -> Result<Self, MasterError> {
        if let Some(first) = drives.first() {
            let period = first.config().cycle_period;
            if let Some(d) = drives.iter().find(|d| d.config().cycle_period != period) {
                return Err(MasterError::GroupPeriod {
                    node: d.node(),
                    period: d.config().cycle_period,
                    first: first.node(),
                    first_period: period,
                });
            }
        }
        let mut enabled: Vec<Drive<B, Enabled>> = Vec::with_capacity(drives.len());
        for d in drives {
            match d.enable() {
                Ok(e) => enabled.push(e),
                Err(err) => {
                    for e in enabled {
                        let _ = e.disable();
                    }
                    return Err(err);
                }
            }
        }
        for d in &mut enabled {
            // the later drives' walks left SYNC answers on the earlier drives' queues
            d.link.exchange.counters = Counters::default();
        }
        let n = enabled.len();
        Ok(Self {
            drives: enabled,
            setpoints: vec![TorqueSetpoint::default(); n],
            cycles: vec![0; n],
            fresh: vec![false; n],
        })
    }

    /// The drives, in axis order.
    pub fn drives(&self) -> &[Drive<B, Enabled>] {
        &self.drives
    }

    /// One cycle: every drive's RPDO1 (Enable operation, `torques_nm[i]` as ‰ of its
    /// rated torque, clamped), one SYNC, every drive's TPDOs until `deadline`, the
    /// feedback into `out` (one per drive). The errors of [`Drive::cycle`], from the first
    /// drive that has one. No allocation.
    pub fn cycle(
        &mut self,
        torques_nm: &[f64],
        deadline: Instant,
        out: &mut [Feedback],
    ) -> Result<(), MasterError> {
        let n = self.drives.len();
        if torques_nm.len() != n || out.len() != n {
            return Err(MasterError::GroupSize {
                axes: n,
                torques: torques_nm.len(),
                feedback: out.len(),
            });
        }
        let mut sync = None;
        for (i, d) in self.drives.iter_mut().enumerate() {
            let l = &mut d.link;
            self.setpoints[i] = l.setpoint(torques_nm[i])?;
            self.cycles[i] = l.exchange.counters.cycles;
            let f = l.exchange_begin(
                Controlword::ENABLE_OPERATION,
                self.setpoints[i].permille,
                Mode::Strict,
                i == 0,
            )?;
            sync.get_or_insert(f);
        }
        let Some(sync) = sync else {
            return Ok(()); // no drives
        };
        let sync_time = self.drives[0].link.now();
        for d in &mut self.drives {
            d.link.exchange_sync_sent(sync_time);
        }
        self.drives[0].link.send(&sync, "sending SYNC")?;
        for (i, d) in self.drives.iter_mut().enumerate() {
            self.fresh[i] = d.link.exchange_collect(deadline, Mode::Strict)?;
        }
        for (i, d) in self.drives.iter_mut().enumerate() {
            out[i] =
                d.link
                    .feedback(self.cycles[i], sync_time, self.fresh[i], self.setpoints[i])?;
        }
        Ok(())
    }

    /// Disables every drive (one after the other; ramp the torques down first). All are
    /// tried; the first error is returned.
    pub fn disable(self) -> Result<Vec<Drive<B, Configured>>, MasterError> {
        let mut done = Vec::with_capacity(self.drives.len());
        let mut first_err = None;
        for d in self.drives {
            match d.disable() {
                Ok(c) => done.push(c),
                Err(e) => {
                    first_err.get_or_insert(e);
                }
            }
        }
        match first_err {
            None => Ok(done),
            Some(e) => Err(e),
        }
    }
}

impl<B: CanBus> MultiAxisDrive for DriveGroup<B> {
    type Error = MasterError;

    fn axes(&self) -> usize {
        self.drives.len()
    }

    fn cycle(
        &mut self,
        torques_nm: &[f64],
        deadline: Instant,
        out: &mut [Feedback],
    ) -> Result<(), MasterError> {
        DriveGroup::cycle(self, torques_nm, deadline, out)
    }

    fn cycle_period(&self) -> Duration {
        self.drives
            .first()
            .map_or(Duration::from_millis(1), |d| d.config().cycle_period)
    }

    fn rated_torque_nm(&self, axis: usize) -> f64 {
        self.drives[axis].link.scaling.rated_torque_nm
    }

    fn node(&self, axis: usize) -> u8 {
        self.drives[axis].node()
    }
}

//! What a [`crate::Runner`] serves on a bus: one drive, or several drives that share the
//! bus (and maybe a plant), as one sans-I/O node.

use std::time::Duration;

use flexid_can::CanFrame;

use crate::drive::{DriveStats, VirtualDrive};
use crate::physics::Physics;

/// A sans-I/O bus participant: frames and time in, frames out through `send`.
pub trait BusNode {
    /// Power-on (boot-up frames, timers started).
    fn power_on(&mut self, now: Duration, send: &mut dyn FnMut(&CanFrame));
    /// One received frame at `now`.
    fn on_frame(&mut self, frame: &CanFrame, now: Duration, send: &mut dyn FnMut(&CanFrame));
    /// Timers at `now`.
    fn tick(&mut self, now: Duration, send: &mut dyn FnMut(&CanFrame));
    /// When [`BusNode::tick`] next has something to do.
    fn next_deadline(&self) -> Option<Duration>;
    /// Counters, summed over the node's drives.
    fn stats(&self) -> DriveStats;
}

impl<P: Physics> BusNode for VirtualDrive<P> {
    fn power_on(&mut self, now: Duration, send: &mut dyn FnMut(&CanFrame)) {
        VirtualDrive::power_on(self, now).iter().for_each(send);
    }
    fn on_frame(&mut self, frame: &CanFrame, now: Duration, send: &mut dyn FnMut(&CanFrame)) {
        VirtualDrive::on_frame(self, frame, now)
            .iter()
            .for_each(send);
    }
    fn tick(&mut self, now: Duration, send: &mut dyn FnMut(&CanFrame)) {
        VirtualDrive::tick(self, now).iter().for_each(send);
    }
    fn next_deadline(&self) -> Option<Duration> {
        VirtualDrive::next_deadline(self)
    }
    fn stats(&self) -> DriveStats {
        VirtualDrive::stats(self)
    }
}

/// Several drives on one bus, served as one node: every frame goes to every drive (each
/// takes what is addressed to it), in node order. With a shared plant
/// ([`crate::robot::RobotPlant`]) all drives sample a SYNC before the plant advances.
pub struct DriveSet<P: Physics> {
    drives: Vec<VirtualDrive<P>>,
}

impl<P: Physics> DriveSet<P> {
    /// The drives, in the order frames are handed to them.
    pub fn new(drives: Vec<VirtualDrive<P>>) -> Self {
        Self { drives }
    }

    /// The drives.
    pub fn drives(&self) -> &[VirtualDrive<P>] {
        &self.drives
    }

    /// The node ids, in order.
    pub fn node_ids(&self) -> Vec<u8> {
        self.drives.iter().map(|d| d.config().node_id).collect()
    }
}

impl<P: Physics> BusNode for DriveSet<P> {
    fn power_on(&mut self, now: Duration, send: &mut dyn FnMut(&CanFrame)) {
        for d in &mut self.drives {
            BusNode::power_on(d, now, send);
        }
    }
    fn on_frame(&mut self, frame: &CanFrame, now: Duration, send: &mut dyn FnMut(&CanFrame)) {
        for d in &mut self.drives {
            BusNode::on_frame(d, frame, now, send);
        }
    }
    fn tick(&mut self, now: Duration, send: &mut dyn FnMut(&CanFrame)) {
        for d in &mut self.drives {
            BusNode::tick(d, now, send);
        }
    }
    fn next_deadline(&self) -> Option<Duration> {
        self.drives.iter().filter_map(|d| d.next_deadline()).min()
    }
    fn stats(&self) -> DriveStats {
        self.drives.iter().fold(DriveStats::default(), |a, d| {
            let s = d.stats();
            DriveStats {
                frames: a.frames + s.frames,
                syncs: a.syncs + s.syncs,
                ignored: a.ignored + s.ignored,
                cycles: a.cycles + s.cycles,
            }
        })
    }
}

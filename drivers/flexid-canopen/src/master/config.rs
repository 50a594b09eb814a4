//! The master's configuration.

use std::time::{Duration, Instant};

/// Settings of the master for one drive. `Default` gives node 1, a 1 ms cycle on a
/// 1 Mbit/s bus.
#[derive(Debug, Clone, Copy)]
pub struct MasterConfig {
    /// The drive's node-id, 1..=127.
    pub node: u8,
    /// The master's own node-id, 1..=127 (its heartbeat COB-ID 0x700 + id, and what the
    /// drive's heartbeat consumer 0x1016:1 watches).
    pub master_node: u8,
    /// SYNC period, written to 0x1006 (µs).
    pub cycle_period: Duration,
    /// Time waited for each SDO response.
    pub sdo_timeout: Duration,
    /// Time waited for the boot-up after the NMT reset.
    pub boot_timeout: Duration,
    /// Period of the master's heartbeat (sent from the cycle).
    pub heartbeat_period: Duration,
    /// Heartbeat consumer time written to the drive (0x1016:1, ms): the drive stops
    /// (heartbeat event) when the master's heartbeat is missing this long.
    pub heartbeat_consumer_time: Duration,
    /// The drive's producer heartbeat period, written to 0x1017 (ms); zero: off.
    pub drive_heartbeat_period: Duration,
    /// Time allowed to walk the CiA 402 state machine (enable, disable, quick stop).
    pub state_timeout: Duration,
    /// Time 0x6061 may take to show the mode (profile quirk `mode-display-lags`).
    pub mode_timeout: Duration,
    /// Consecutive cycles without feedback before the cycle fails: the least count; the
    /// limit applied is [`MasterConfig::missed_cycles_limit`] (this many cycles and at least
    /// [`MasterConfig::max_missed_time`] worth of them).
    pub max_missed_cycles: u32,
    /// The shortest run of cycles without feedback that fails the cycle, as a time (default
    /// 50 ms; below `heartbeat_consumer_time`, checked by [`MasterConfig::validate`]).
    ///
    /// Why a time and not only a count: 10 cycles are 10 ms at 1 kHz but 2.5 ms at 4 kHz,
    /// shorter than one scheduling stall of a host without a real-time kernel (a
    /// `CONFIG_PREEMPT_NONE` VM holds even a `SCHED_FIFO` thread off its CPU for up to
    /// ~15 ms), so a fast cycle failed on every such stall. A drive that has really gone
    /// silent is still caught within 50 ms, well before its own heartbeat consumer (300 ms
    /// by default) would stop it; the sweep's lost-feedback budget counts every loss.
    pub max_missed_time: Duration,
    /// Bus bitrate, bits/s (for the bus-load check).
    pub bitrate: u32,
    /// Largest admissible bus load (fraction; CANopen practice 0.7).
    pub max_bus_load: f64,
    /// When CAN error frames stop the cycle (a single one does not; error passive, bus-off
    /// or a burst does): [`super::error_frames`].
    pub error_frames: super::ErrorFramePolicy,
    /// The time source (inject a fake one in tests).
    pub clock: fn() -> Instant,
}

impl Default for MasterConfig {
    fn default() -> Self {
        Self {
            node: 1,
            master_node: 0x7F,
            cycle_period: Duration::from_millis(1),
            sdo_timeout: Duration::from_millis(500),
            boot_timeout: Duration::from_secs(5),
            heartbeat_period: Duration::from_millis(100),
            heartbeat_consumer_time: Duration::from_millis(300),
            drive_heartbeat_period: Duration::from_millis(100),
            state_timeout: Duration::from_secs(2),
            mode_timeout: Duration::from_millis(100),
            max_missed_cycles: 10,
            max_missed_time: Duration::from_millis(50),
            bitrate: 1_000_000,
            max_bus_load: 0.7,
            error_frames: super::ErrorFramePolicy::default(),
            clock: Instant::now,
        }
    }
}

impl MasterConfig {
    /// The default configuration for drive `node`.
    pub fn for_node(node: u8) -> Self {
        Self {
            node,
            ..Self::default()
        }
    }

    /// Consecutive cycles without feedback that fail the cycle: `max_missed_cycles`, or
    /// more when those are shorter than `max_missed_time` at `cycle_period`.
    pub fn missed_cycles_limit(&self) -> u32 {
        let period_ns = self.cycle_period.as_nanos().max(1);
        let by_time = self.max_missed_time.as_nanos().div_ceil(period_ns);
        self.max_missed_cycles
            .max(by_time.min(u32::MAX as u128) as u32)
    }

    /// Checks ranges; the message says which field is wrong.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=127).contains(&self.node) {
            return Err(format!("node {} outside 1..=127", self.node));
        }
        if !(1..=127).contains(&self.master_node) || self.master_node == self.node {
            return Err(format!(
                "master_node {} outside 1..=127 or equal to the drive's",
                self.master_node
            ));
        }
        if self.cycle_period.is_zero() || self.cycle_period.as_micros() > u32::MAX as u128 {
            return Err(format!("cycle_period {:?} out of range", self.cycle_period));
        }
        if self.heartbeat_consumer_time.as_millis() > u16::MAX as u128
            || self.drive_heartbeat_period.as_millis() > u16::MAX as u128
        {
            return Err("heartbeat times above 65535 ms".into());
        }
        if self.heartbeat_period.is_zero() || self.heartbeat_period >= self.heartbeat_consumer_time
        {
            return Err(format!(
                "heartbeat_period {:?} must be positive and below heartbeat_consumer_time {:?}",
                self.heartbeat_period, self.heartbeat_consumer_time
            ));
        }
        if self.max_missed_cycles == 0 || self.max_missed_time >= self.heartbeat_consumer_time {
            return Err(format!(
                "max_missed_cycles must be positive and max_missed_time {:?} below \
                 heartbeat_consumer_time {:?}",
                self.max_missed_time, self.heartbeat_consumer_time
            ));
        }
        if self.bitrate == 0 || !(self.max_bus_load > 0.0 && self.max_bus_load <= 1.0) {
            return Err("bitrate must be positive and max_bus_load in (0, 1]".into());
        }
        self.error_frames.validate()
    }
}

//! The blocking runner: a drive ([`crate::VirtualDrive`]) or a set of drives
//! ([`crate::DriveSet`]) on any [`CanBus`], on the calling thread.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use flexid_can::{BusError, CanBus};

use flexid_can::CanFrame;

use crate::node::BusNode;

/// Longest wait in `recv_timeout`, so that a stop request is seen promptly.
pub const POLL: Duration = Duration::from_millis(20);
/// Most queued frames handled before the timers are looked at (a flooded bus must not
/// starve the heartbeat).
pub const MAX_DRAIN: usize = 64;

/// Errors of the runner.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The bus failed (not a report such as an error frame: those are logged).
    #[error("bus {interface}: {source}")]
    Bus {
        interface: String,
        #[source]
        source: BusError,
    },
}

/// A drive (or a set of drives) on a bus.
pub struct Runner<B: CanBus, N: BusNode> {
    bus: B,
    drive: N,
    epoch: Instant,
    send_errors: u64,
}

impl<B: CanBus, N: BusNode> Runner<B, N> {
    /// The drive on `bus`; time 0 is now.
    pub fn new(bus: B, drive: N) -> Self {
        Self {
            bus,
            drive,
            epoch: Instant::now(),
            send_errors: 0,
        }
    }

    /// The drive.
    pub fn drive(&self) -> &N {
        &self.drive
    }

    /// The bus's name (`udp:239.74.163.2:43113`, `vcan0`, ...).
    pub fn interface(&self) -> &str {
        self.bus.interface()
    }

    /// Frames that could not be sent.
    pub fn send_errors(&self) -> u64 {
        self.send_errors
    }

    /// Boots the drive (boot-up frame), then serves the bus until `stop` is set. Bus
    /// reports (error frames, overruns) are logged and survived; a broken bus ends the run.
    pub fn run(&mut self, stop: &AtomicBool) -> Result<(), RunError> {
        self.power_on();
        self.serve(stop)
    }

    /// Boots the drive: sends the boot-up frame.
    pub fn power_on(&mut self) {
        let now = self.epoch.elapsed();
        let (bus, errors) = (&mut self.bus, &mut self.send_errors);
        self.drive.power_on(now, &mut |f| send(bus, errors, f));
    }

    /// Serves the bus until `stop` is set (after [`Runner::power_on`]).
    pub fn serve(&mut self, stop: &AtomicBool) -> Result<(), RunError> {
        while !stop.load(Ordering::Relaxed) {
            // Frames already queued first: a drive that was itself descheduled must see
            // the SYNCs that did arrive (at their receive stamps) before its timers judge
            // them missing.
            for _ in 0..MAX_DRAIN {
                if !self.receive(Duration::ZERO)? {
                    break;
                }
            }
            let now = self.epoch.elapsed();
            let (bus, errors) = (&mut self.bus, &mut self.send_errors);
            self.drive.tick(now, &mut |f| send(bus, errors, f));
            let wait = self
                .drive
                .next_deadline()
                .map_or(POLL, |d| d.saturating_sub(now).min(POLL));
            self.receive(wait)?;
        }
        Ok(())
    }

    /// Waits up to `wait` for one frame and hands it to the drive; whether one came.
    fn receive(&mut self, wait: Duration) -> Result<bool, RunError> {
        match self.bus.recv_timeout(wait) {
            Ok(Some(r)) => {
                let at = r.timestamp.saturating_duration_since(self.epoch);
                let (bus, errors) = (&mut self.bus, &mut self.send_errors);
                self.drive
                    .on_frame(&r.frame, at, &mut |f| send(bus, errors, f));
                Ok(true)
            }
            Ok(None) => Ok(false),
            Err(e) if e.is_report() => {
                tracing::warn!("{e}");
                Ok(true)
            }
            Err(source) => Err(RunError::Bus {
                interface: self.bus.interface().to_string(),
                source,
            }),
        }
    }
}

/// Sends `f` on `bus`; a failure is counted in `errors` and logged.
fn send<B: CanBus>(bus: &mut B, errors: &mut u64, f: &CanFrame) {
    if let Err(e) = bus.send(f) {
        *errors += 1;
        tracing::warn!("send {f}: {e}");
    }
}

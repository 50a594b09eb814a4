//! In-process bus for unit tests: handles on one shared medium, CAN-like fan-out.
//!
//! Every frame sent through one handle is put, in one step under the medium's lock, into
//! the receive queue of every other handle, so all receivers see one global order (the
//! order in which `send` calls took the lock). The sender does not receive its own frame.
//! Each queue is bounded (default [`InprocBus::DEFAULT_CAPACITY`] frames): when a handle
//! does not read, further frames for it are dropped and reported once as
//! [`BusError::Overrun`], as a controller's receive FIFO would.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use crate::bus::{BusStats, CanBus};
use crate::error::BusError;
use crate::frame::{CanFrame, Received};

/// One handle on an in-process bus.
#[derive(Debug)]
pub struct InprocBus {
    medium: Arc<Medium>,
    port: Arc<Port>,
    stats: BusStats,
}

#[derive(Debug)]
struct Medium {
    name: Arc<str>,
    capacity: usize,
    next_port: AtomicU64,
    ports: Mutex<Vec<Arc<Port>>>,
}

#[derive(Debug)]
struct Port {
    id: u64,
    queue: Mutex<Queue>,
    ready: Condvar,
}

#[derive(Debug)]
struct Queue {
    frames: VecDeque<Received>,
    /// Frames dropped since the last report.
    lost: u64,
}

/// Locks, ignoring poisoning: the guarded data stays consistent (plain pushes and pops).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl InprocBus {
    /// Receive queue length per handle, in frames.
    pub const DEFAULT_CAPACITY: usize = 4096;

    /// A new medium with one handle on it. `name` appears in errors as `inproc:<name>`.
    pub fn new(name: &str) -> Self {
        Self::with_capacity(name, Self::DEFAULT_CAPACITY)
    }

    /// A new medium whose handles queue at most `capacity` received frames each.
    pub fn with_capacity(name: &str, capacity: usize) -> Self {
        let medium = Arc::new(Medium {
            name: format!("inproc:{name}").into(),
            capacity: capacity.max(1),
            next_port: AtomicU64::new(0),
            ports: Mutex::new(Vec::new()),
        });
        Self::attach(medium)
    }

    fn attach(medium: Arc<Medium>) -> Self {
        let port = Arc::new(Port {
            id: medium.next_port.fetch_add(1, Ordering::Relaxed),
            queue: Mutex::new(Queue {
                frames: VecDeque::with_capacity(medium.capacity.min(256)),
                lost: 0,
            }),
            ready: Condvar::new(),
        });
        lock(&medium.ports).push(port.clone());
        Self {
            medium,
            port,
            stats: BusStats::default(),
        }
    }

    /// A new handle on the same medium (infallible form of [`CanBus::try_clone`]).
    pub fn handle(&self) -> Self {
        Self::attach(self.medium.clone())
    }

    /// Number of handles currently on the medium.
    pub fn handles(&self) -> usize {
        lock(&self.medium.ports).len()
    }
}

impl Drop for InprocBus {
    fn drop(&mut self) {
        lock(&self.medium.ports).retain(|p| p.id != self.port.id);
    }
}

impl InprocBus {
    /// Puts `frame`, received at `timestamp`, into every other handle's queue.
    fn push(&mut self, frame: &CanFrame, timestamp: Instant) {
        let ports = lock(&self.medium.ports);
        let received = Received {
            frame: *frame,
            timestamp,
        };
        for port in ports.iter().filter(|p| p.id != self.port.id) {
            let mut q = lock(&port.queue);
            if q.frames.len() >= self.medium.capacity {
                q.lost += 1;
            } else {
                q.frames.push_back(received);
            }
            drop(q);
            port.ready.notify_one();
        }
        self.stats.sent += 1;
    }
}

impl CanBus for InprocBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        self.push(frame, Instant::now());
        Ok(())
    }

    /// Stamps the frame with `due` at once (no wait): [`crate::timing::Paced`] receivers
    /// deliver it no earlier.
    fn send_due(&mut self, frame: &CanFrame, due: Instant) -> Result<(), BusError> {
        self.push(frame, due);
        Ok(())
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, BusError> {
        let deadline = Instant::now().checked_add(timeout);
        let mut q = lock(&self.port.queue);
        loop {
            if q.lost > 0 {
                let lost = std::mem::take(&mut q.lost);
                self.stats.lost += lost;
                return Err(BusError::Overrun {
                    interface: self.medium.name.clone(),
                    lost,
                });
            }
            if let Some(r) = q.frames.pop_front() {
                if r.frame.is_error() {
                    self.stats.error_frames += 1;
                    return Err(BusError::from_error_frame(&self.medium.name, &r.frame));
                }
                self.stats.received += 1;
                return Ok(Some(r));
            }
            let left = match deadline {
                Some(d) => d.saturating_duration_since(Instant::now()),
                None => Duration::MAX,
            };
            if left.is_zero() {
                return Ok(None);
            }
            q = self
                .port
                .ready
                .wait_timeout(q, left)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    fn try_clone(&self) -> Result<Self, BusError> {
        Ok(self.handle())
    }

    fn interface(&self) -> &str {
        &self.medium.name
    }

    fn stats(&self) -> BusStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(id: u16, b: u8) -> CanFrame {
        CanFrame::standard(id, &[b]).unwrap()
    }

    #[test]
    fn fan_out_excludes_sender_and_keeps_order() {
        let mut a = InprocBus::new("t");
        let mut b = a.handle();
        let mut c = b.try_clone().unwrap();
        assert_eq!(a.handles(), 3);
        for i in 0..10 {
            a.send(&frame(0x100, i)).unwrap();
        }
        c.send(&frame(0x200, 99)).unwrap();
        let z = Duration::ZERO;
        for i in 0..10 {
            assert_eq!(b.recv_timeout(z).unwrap().unwrap().frame, frame(0x100, i));
            assert_eq!(c.recv_timeout(z).unwrap().unwrap().frame, frame(0x100, i));
        }
        assert_eq!(b.recv_timeout(z).unwrap().unwrap().frame, frame(0x200, 99));
        assert_eq!(a.recv_timeout(z).unwrap().unwrap().frame, frame(0x200, 99));
        for h in [&mut a, &mut b, &mut c] {
            assert!(
                h.recv_timeout(z).unwrap().is_none(),
                "sender got its own frame"
            );
        }
        drop(c);
        assert_eq!(a.handles(), 2);
        assert_eq!(b.stats().received, 11);
    }

    #[test]
    fn overrun_is_reported_once_then_reading_goes_on() {
        let mut a = InprocBus::with_capacity("t", 2);
        let mut b = a.handle();
        for i in 0..5 {
            a.send(&frame(1, i)).unwrap();
        }
        let z = Duration::ZERO;
        assert!(matches!(
            b.recv_timeout(z),
            Err(BusError::Overrun { lost: 3, .. })
        ));
        assert_eq!(b.recv_timeout(z).unwrap().unwrap().frame, frame(1, 0));
        assert_eq!(b.recv_timeout(z).unwrap().unwrap().frame, frame(1, 1));
        assert!(b.recv_timeout(z).unwrap().is_none());
    }

    #[test]
    fn error_frames_are_reported_as_errors() {
        let mut a = InprocBus::new("t");
        let mut b = a.handle();
        a.send(&CanFrame::error(0x40, [0; 8]).unwrap()).unwrap();
        a.send(&frame(5, 5)).unwrap();
        let z = Duration::ZERO;
        assert!(matches!(b.recv_timeout(z), Err(BusError::BusOff { .. })));
        assert_eq!(b.recv_timeout(z).unwrap().unwrap().frame, frame(5, 5));
    }

    #[test]
    fn recv_waits_for_another_thread() {
        let mut a = InprocBus::new("t");
        let mut b = a.handle();
        let t = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            a.send(&frame(7, 7)).unwrap();
        });
        let r = b.recv_timeout(Duration::from_secs(10)).unwrap().unwrap();
        assert_eq!(r.frame, frame(7, 7));
        t.join().unwrap();
        assert!(b.recv_timeout(Duration::from_millis(5)).unwrap().is_none());
    }
}

//! Lost feedback on purpose: [`LosingDrive`] wraps any drive and, at chosen cycles, reports
//! the previous cycle's values with `fresh: false`, as the CANopen master does when a TPDO
//! misses its deadline, while the drive underneath moves on. For tests of what a sweep makes
//! of lost feedback, against the simulated drive or any other.

use flexid_canopen::{Counters, CyclicDrive, Feedback};
use std::time::{Duration, Instant};

/// `inner` with its feedback lost at the cycles in `lose` (0-based from the first cycle).
pub struct LosingDrive<D> {
    inner: D,
    lose: Vec<usize>,
    k: usize,
    last: Option<Feedback>,
    lost: u64,
}

impl<D> LosingDrive<D> {
    /// `inner`, losing the feedback of the cycles in `lose`.
    pub fn new(inner: D, mut lose: Vec<usize>) -> Self {
        lose.sort_unstable();
        LosingDrive {
            inner,
            lose,
            k: 0,
            last: None,
            lost: 0,
        }
    }
}

impl<D: CyclicDrive> CyclicDrive for LosingDrive<D> {
    type Error = D::Error;

    fn cycle(&mut self, torque_nm: f64, deadline: Instant) -> Result<Feedback, D::Error> {
        let fb = self.inner.cycle(torque_nm, deadline)?;
        let k = self.k;
        self.k += 1;
        let out = match (&self.last, self.lose.binary_search(&k).is_ok()) {
            (Some(prev), true) => {
                self.lost += 1;
                Feedback {
                    position_rad: prev.position_rad,
                    velocity_rad_s: prev.velocity_rad_s,
                    torque_nm: prev.torque_nm,
                    fresh: false,
                    // the values are not the drive cycle's the frame read
                    drive_cycle: None,
                    counters: self.counters_with(fb.counters),
                    ..fb
                }
            }
            _ => Feedback {
                counters: self.counters_with(fb.counters),
                ..fb
            },
        };
        // the values a later lost cycle repeats: the last ones that arrived
        if out.fresh {
            self.last = Some(fb);
        }
        Ok(out)
    }

    fn cycle_period(&self) -> Duration {
        self.inner.cycle_period()
    }

    fn rated_torque_nm(&self) -> f64 {
        self.inner.rated_torque_nm()
    }

    fn counters(&self) -> Counters {
        self.counters_with(self.inner.counters())
    }

    /// The wrapped drive's classification.
    fn error_kind(error: &Self::Error) -> Option<flexid_canopen::DriveErrorKind> {
        D::error_kind(error)
    }
}

impl<D> LosingDrive<D> {
    fn counters_with(&self, mut c: Counters) -> Counters {
        c.missed += self.lost;
        c.lost += self.lost;
        c
    }
}

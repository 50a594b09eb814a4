//! Rows recorded from a lost feedback, filled in the sweep loop before anyone reads them.
//!
//! When a drive's feedback (TPDO) misses its cycle, the master reports the previous values
//! (`fresh: false`). One such held position among tens of thousands is a step of one
//! cycle's motion, whose difference is a broadband impulse in the velocity: it turned a
//! 380/590 Hz pair's phase rise from 180 to 37 deg and made an identification of three
//! bodies report two. A held row is therefore replaced by the linear interpolation between
//! the nearest fresh rows on either side (held from the one side at the ends), and rewritten
//! into the sink as soon as the fresh row after it arrives.
//!
//! Every sink gets the filled rows (the command line's [`crate::RecordedRows`] and the
//! daemon's per-period stream alike); the loop holds back its progress report (which
//! publishes rows to the daemon's relay) while a held row waits for its fill. Nothing here
//! allocates after [`StaleFill::with_capacity`]: it runs in the real-time cycle.

use crate::rows::{Row, RowSink};

/// The fill of held rows: the last fresh row and the run of held rows after it.
#[derive(Debug)]
pub struct StaleFill {
    /// The last fresh row and its index.
    last_fresh: Option<(usize, Row)>,
    /// Index of the first held row waiting for its fill.
    pending_from: usize,
    /// The held rows waiting (their set-points are kept: only the feedback is filled).
    pending: Vec<Row>,
    /// Held rows seen in the whole sweep.
    held: u64,
}

impl StaleFill {
    /// Room for `max_run` consecutive held rows (allocated here, once). Rows beyond a run of
    /// that length keep their held values (the sweep stops beyond its budget of lost
    /// feedback anyway).
    pub fn with_capacity(max_run: usize) -> Self {
        StaleFill {
            last_fresh: None,
            pending_from: 0,
            pending: Vec::with_capacity(max_run),
            held: 0,
        }
    }

    /// Row `k`, `fresh` or held, into `sink`; after a fresh row, the held rows before it
    /// are rewritten into `sink`, filled.
    pub fn push(&mut self, k: usize, row: &Row, fresh: bool, sink: &mut dyn RowSink) {
        sink.push(k, row);
        if !fresh {
            self.held += 1;
            if self.pending.is_empty() {
                self.pending_from = k;
            }
            if self.pending.len() < self.pending.capacity() {
                self.pending.push(*row);
            }
            return;
        }
        for (i, held) in self.pending.iter().enumerate() {
            let j = self.pending_from + i;
            let filled = match self.last_fresh {
                Some((a, before)) => {
                    let w = (j - a) as f64 / (k - a) as f64;
                    Row {
                        torque_setpoint_nm: held.torque_setpoint_nm,
                        position_rad: lerp(before.position_rad, row.position_rad, w),
                        velocity_rad_s: lerp(before.velocity_rad_s, row.velocity_rad_s, w),
                        torque_actual_nm: lerp(before.torque_actual_nm, row.torque_actual_nm, w),
                    }
                }
                // held rows before the first fresh one: held from after
                None => Row {
                    torque_setpoint_nm: held.torque_setpoint_nm,
                    ..*row
                },
            };
            sink.push(j, &filled);
        }
        self.pending.clear();
        self.last_fresh = Some((k, *row));
    }

    /// Sets the torque set-point of row `k`, the last one pushed (a later set-point reached
    /// the drive in the same cycle and replaced it), in the fill and in `sink`. Returns
    /// false, changing nothing, when `k` is not the last row pushed.
    pub fn set_last_setpoint(&mut self, k: usize, torque_nm: f64, sink: &mut dyn RowSink) -> bool {
        let last_pending = self.pending_from + self.pending.len();
        if let Some(held) = self.pending.last_mut() {
            if last_pending - 1 != k {
                return false;
            }
            held.torque_setpoint_nm = torque_nm;
            sink.push(k, held);
            return true;
        }
        match &mut self.last_fresh {
            Some((j, row)) if *j == k => {
                row.torque_setpoint_nm = torque_nm;
                sink.push(k, row);
                true
            }
            _ => false,
        }
    }

    /// Whether a held row is waiting for the fresh row after it.
    pub fn waiting(&self) -> bool {
        !self.pending.is_empty()
    }

    /// Held rows seen so far (filled or waiting).
    pub fn held(&self) -> u64 {
        self.held
    }
}

fn lerp(a: f64, b: f64, w: f64) -> f64 {
    a + w * (b - a)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sink that writes row k at index k (as the daemon's does).
    struct Indexed(Vec<Row>);

    impl RowSink for Indexed {
        fn push(&mut self, k: usize, row: &Row) {
            self.0[k] = *row;
        }
    }

    fn row(k: usize) -> Row {
        let t = k as f64;
        Row {
            torque_setpoint_nm: 0.1 * t,
            position_rad: 2.0 * t,
            velocity_rad_s: 3.0 - t,
            torque_actual_nm: 0.5 * t,
        }
    }

    /// Feedback linear in k is recovered exactly between fresh rows, wherever the held
    /// rows are (a run of three, single ones; the first row is held from after, the last
    /// from before), and each fill is in the sink as soon
    /// as the fresh row after it has been pushed.
    #[test]
    fn held_rows_become_the_interpolation_of_their_fresh_neighbours() {
        let n = 20;
        let held = [0usize, 5, 6, 7, 12, 19];
        let mut sink = Indexed(vec![row(0); n]);
        let mut fill = StaleFill::with_capacity(4);
        let mut last_fresh = row(0);
        for k in 0..n {
            let fresh = !held.contains(&k);
            let r = if fresh {
                row(k)
            } else {
                Row {
                    torque_setpoint_nm: row(k).torque_setpoint_nm,
                    ..last_fresh
                }
            };
            if fresh {
                last_fresh = r;
            }
            fill.push(k, &r, fresh, &mut sink);
            assert_eq!(fill.waiting(), !fresh, "row {k}");
            if fresh {
                // row 0 has no fresh row before it: held from row 1
                let first = Row {
                    torque_setpoint_nm: row(0).torque_setpoint_nm,
                    ..row(1)
                };
                assert_eq!(sink.0[0], first);
                for j in 1..=k {
                    assert_eq!(sink.0[j], row(j), "row {j} after pushing {k}");
                }
            }
        }
        // the last row is held from before
        assert_eq!(sink.0[19].position_rad, row(18).position_rad);
        assert_eq!(sink.0[19].torque_setpoint_nm, row(19).torque_setpoint_nm);
        assert_eq!(fill.held(), held.len() as u64);
    }

    /// A run longer than the room keeps the held values beyond the room, never panics.
    #[test]
    fn a_run_longer_than_the_room_keeps_the_rest_held() {
        let mut sink = Indexed(vec![row(0); 6]);
        let mut fill = StaleFill::with_capacity(1);
        fill.push(0, &row(0), true, &mut sink);
        let held = Row {
            torque_setpoint_nm: 0.0,
            ..row(0)
        };
        fill.push(1, &held, false, &mut sink);
        fill.push(2, &held, false, &mut sink);
        fill.push(3, &row(3), true, &mut sink);
        assert_eq!(sink.0[1].position_rad, row(1).position_rad);
        assert_eq!(sink.0[2].position_rad, row(0).position_rad);
        assert_eq!(sink.0[3], row(3));
    }
}

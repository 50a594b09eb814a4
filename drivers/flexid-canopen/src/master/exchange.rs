//! The sans-I/O core of one cycle: builds the frames to send and classifies every
//! received frame. The blocking layer ([`super::Drive::cycle`]) only moves frames and
//! time in and out. No allocation.
//!
//! # Which cycle a TPDO answers
//!
//! The drive sends its synchronous TPDOs after it receives a SYNC, so a TPDO that
//! arrived before this cycle's SYNC was sent cannot answer it: it answers an earlier
//! SYNC. Every frame is therefore classified by when it *arrived* (the bus's receive
//! time stamp, [`flexid_can::Received::timestamp`]) relative to when this cycle's SYNC
//! was sent ([`Exchange::sync_sent`]), not by when it was read: a late TPDO of the
//! previous cycle that lands just after the drain but is read during this cycle's wait
//! is counted late and never used as this cycle's feedback. (The default profile has
//! no SYNC counter, 0x1019 = 0, and a TPDO carries none: a TPDO more than one whole
//! cycle late, arriving after the next SYNC, is indistinguishable from that cycle's.)

use std::time::Instant;

use canopen_rs::EmergencyMessage;
use flexid_can::CanFrame;

use crate::cob::{self, Cob};
use crate::drive::Counters;
use crate::pdo::{pack_rpdo1, Tpdo1, Tpdo2};

const GOT1: u8 = 1;
const GOT2: u8 = 2;
const ALL: u8 = GOT1 | GOT2;

/// Which cycle a received frame belongs to, from its arrival time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Arrived before this cycle's SYNC was sent (or read between cycles): an earlier
    /// cycle's.
    Before,
    /// Arrived after this cycle's SYNC was sent, read before its deadline.
    Answer,
}

/// What a received frame meant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// This cycle's TPDO1 or TPDO2 (stored).
    Feedback,
    /// The previous cycle's missing TPDO, arrived after its deadline (counted late, not
    /// used).
    Late,
    /// An emergency from the drive with a non-zero error code.
    Emergency(EmergencyMessage),
    /// The drive's heartbeat with a state byte other than Operational (0x05).
    NmtState(u8),
    /// Counted and ignored.
    Ignored,
    /// Counted as malformed and ignored.
    Malformed,
}

/// Per-cycle bookkeeping of the default mapping's exchange.
#[derive(Debug, Clone)]
pub struct Exchange {
    node: u8,
    got: u8,
    missing_prev: u8,
    /// When this cycle's SYNC was sent; `None` between cycles (after [`Exchange::end`]).
    sync_at: Option<Instant>,
    consecutive_missed: u32,
    /// Latest TPDO1.
    pub tpdo1: Tpdo1,
    /// Latest TPDO2.
    pub tpdo2: Tpdo2,
    /// Counters.
    pub counters: Counters,
}

impl Exchange {
    /// A fresh exchange with drive `node`.
    pub fn new(node: u8) -> Self {
        Self {
            node,
            got: 0,
            missing_prev: 0,
            sync_at: None,
            consecutive_missed: 0,
            tpdo1: Tpdo1::default(),
            tpdo2: Tpdo2::default(),
            counters: Counters::default(),
        }
    }

    /// Ends the drain phase and returns this cycle's RPDO1 and SYNC, in sending order;
    /// call [`Exchange::sync_sent`] with the time just before the SYNC goes out. The
    /// previous cycle's missing TPDOs are still counted late if they turn out to have
    /// arrived before that SYNC, lost if not.
    pub fn begin(&mut self, controlword: u16, torque_permille: i16) -> [CanFrame; 2] {
        self.got = 0;
        self.sync_at = None;
        let rpdo = CanFrame::standard(
            cob::rpdo(1, self.node),
            &pack_rpdo1(controlword, torque_permille),
        )
        .expect("4 bytes on an 11-bit id");
        let sync = CanFrame::standard(cob::SYNC, &[]).expect("0 bytes on an 11-bit id");
        [rpdo, sync]
    }

    /// Records when this cycle's SYNC was sent (read just before sending it): frames
    /// that arrived before are an earlier cycle's, those after answer this SYNC.
    pub fn sync_sent(&mut self, at: Instant) {
        self.sync_at = Some(at);
    }

    /// Whether all of this cycle's TPDOs are in.
    pub fn complete(&self) -> bool {
        self.got == ALL
    }

    /// Ends the wait (deadline reached or complete): counts the missing TPDOs;
    /// returns whether the cycle was complete and the consecutive incomplete cycles.
    pub fn end(&mut self) -> (bool, u32) {
        // the previous cycle's TPDOs not arrived before this SYNC never will (in order)
        self.counters.lost += self.missing_prev.count_ones() as u64;
        self.sync_at = None;
        self.counters.cycles += 1;
        let missing = ALL & !self.got;
        self.counters.missed += missing.count_ones() as u64;
        self.missing_prev = missing;
        if missing == 0 {
            self.consecutive_missed = 0;
        } else {
            self.consecutive_missed += 1;
        }
        (missing == 0, self.consecutive_missed)
    }

    /// Classifies one received frame that arrived at `arrived_at` (the bus's receive
    /// time stamp) (never panics).
    pub fn on_frame(&mut self, frame: &CanFrame, arrived_at: Instant) -> Event {
        let node = self.node;
        let phase = match self.sync_at {
            Some(sync) if arrived_at >= sync => Phase::Answer,
            _ => Phase::Before,
        };
        let ev = match cob::classify(frame) {
            Cob::Tpdo(n @ 1..=2, id) if id == node => {
                let bit = if n == 1 { GOT1 } else { GOT2 };
                match phase {
                    Phase::Before if self.missing_prev & bit != 0 => {
                        self.missing_prev &= !bit;
                        self.counters.late += 1;
                        // it answers the previous SYNC: stale, not this cycle's sample
                        return Event::Late;
                    }
                    Phase::Before => Event::Ignored, // a duplicate or older: stale
                    Phase::Answer if self.got & bit != 0 => Event::Ignored, // duplicate
                    Phase::Answer => {
                        let ok = if n == 1 {
                            Tpdo1::unpack(frame.data()).map(|t| self.tpdo1 = t).is_ok()
                        } else {
                            Tpdo2::unpack(frame.data()).map(|t| self.tpdo2 = t).is_ok()
                        };
                        if ok {
                            self.got |= bit;
                            return Event::Feedback;
                        }
                        Event::Malformed
                    }
                }
            }
            Cob::Emcy(id) if id == node => match EmergencyMessage::decode(frame.data()) {
                Ok(m) if m.is_error_reset() => Event::Ignored,
                Ok(m) => return Event::Emergency(m),
                Err(_) => Event::Malformed,
            },
            Cob::Heartbeat(id) if id == node => match frame.data() {
                [0x05] => Event::Ignored,
                [s] => return Event::NmtState(*s),
                _ => Event::Malformed,
            },
            _ => Event::Ignored,
        };
        match ev {
            Event::Malformed => self.counters.malformed += 1,
            Event::Ignored => self.counters.ignored += 1,
            _ => {}
        }
        ev
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn f(id: u16, d: &[u8]) -> CanFrame {
        CanFrame::standard(id, d).unwrap()
    }

    fn us(t0: Instant, micros: u64) -> Instant {
        t0 + Duration::from_micros(micros)
    }

    /// Begins a cycle (Enable operation, torque 0) whose SYNC goes out at `micros`.
    fn sync_at(x: &mut Exchange, t0: Instant, micros: u64) {
        x.begin(0x000F, 0);
        x.sync_sent(us(t0, micros));
    }

    #[test]
    fn classifies_and_counts() {
        let t0 = Instant::now();
        let mut x = Exchange::new(3);
        let [rpdo, sync] = x.begin(0x000F, -2);
        x.sync_sent(us(t0, 0));
        assert_eq!(rpdo, f(0x203, &[0x0F, 0x00, 0xFE, 0xFF]));
        assert_eq!(sync, f(0x080, &[]));
        assert_eq!(
            x.on_frame(&f(0x183, &[0x27, 0, 1, 0, 0, 0, 5, 0]), us(t0, 10)),
            Event::Feedback
        );
        assert_eq!(
            x.tpdo1,
            Tpdo1 {
                statusword: 0x27,
                position: 1,
                torque: 5
            }
        );
        assert_eq!(x.on_frame(&f(0x283, &[1, 2]), us(t0, 11)), Event::Malformed);
        assert_eq!(x.on_frame(&f(0x184, &[0; 8]), us(t0, 12)), Event::Ignored);
        assert_eq!(x.on_frame(&f(0x083, &[0; 3]), us(t0, 13)), Event::Malformed);
        assert_eq!(x.on_frame(&f(0x083, &[0; 8]), us(t0, 14)), Event::Ignored); // reset
        assert_eq!(
            x.on_frame(&f(0x703, &[0x7F]), us(t0, 15)),
            Event::NmtState(0x7F)
        );
        assert!(!x.complete());
        assert_eq!(x.end(), (false, 1));
        // TPDO2 arrives late, during the next drain
        assert_eq!(x.on_frame(&f(0x283, &[0; 4]), us(t0, 900)), Event::Late);
        sync_at(&mut x, t0, 1000);
        assert_eq!(x.counters.missed, 1);
        assert_eq!(x.counters.late, 1);
        assert_eq!(x.end(), (false, 2));
        assert_eq!(x.counters.lost, 0);
        sync_at(&mut x, t0, 2000);
        x.end();
        assert_eq!(x.counters.lost, 2, "cycle 2's TPDO1 and TPDO2 never came");
        assert_eq!(x.counters.malformed, 2);
    }

    /// One cycle of the default mapping as the drive answers it: TPDO1 (statusword
    /// Operation enabled, `position`, torque 0) and TPDO2 (`velocity`), as bytes.
    fn answer(position: i32, velocity: i32) -> [CanFrame; 2] {
        let p = position.to_le_bytes();
        let v = velocity.to_le_bytes();
        [
            f(0x185, &[0x27, 0x00, p[0], p[1], p[2], p[3], 0x00, 0x00]),
            f(0x285, &[v[0], v[1], v[2], v[3]]),
        ]
    }

    /// The known defect, replayed: cycle 1's TPDOs miss its deadline and arrive just
    /// after cycle 2's drain, before cycle 2's SYNC goes out, but are read in cycle 2's
    /// wait. They answer SYNC 1: counted late, never used as cycle 2's sample; cycle 2's
    /// own TPDOs that follow are.
    #[test]
    fn a_late_tpdo_read_after_the_next_sync_is_not_that_cycles_sample() {
        let t0 = Instant::now();
        let mut x = Exchange::new(5);
        // cycle 0: answered in time
        sync_at(&mut x, t0, 0);
        for fr in answer(100, 7) {
            assert_eq!(x.on_frame(&fr, us(t0, 200)), Event::Feedback);
        }
        assert_eq!(x.end(), (true, 0));
        // cycle 1: SYNC at 1000 us, nothing by its deadline (2000 us)
        sync_at(&mut x, t0, 1000);
        assert_eq!(x.end(), (false, 1));
        // cycle 2: the drain found nothing; RPDO1 and SYNC go out at 2050 us. Cycle 1's
        // answer arrived at 2040 us (after the drain, before this SYNC) and is read
        // now, in the wait, followed by cycle 2's own answer at 2250 us.
        sync_at(&mut x, t0, 2050);
        let [late1, late2] = answer(111, 11);
        assert_eq!(x.on_frame(&late1, us(t0, 2040)), Event::Late);
        assert_eq!(x.on_frame(&late2, us(t0, 2040)), Event::Late);
        assert!(!x.complete(), "a stale answer does not complete the cycle");
        assert_eq!(
            x.tpdo1.position, 100,
            "cycle 1's position not taken for cycle 2"
        );
        assert_eq!(x.tpdo2.velocity, 7);
        let [own1, own2] = answer(222, 22);
        assert_eq!(x.on_frame(&own1, us(t0, 2250)), Event::Feedback);
        assert_eq!(x.on_frame(&own2, us(t0, 2251)), Event::Feedback);
        assert!(x.complete());
        assert_eq!((x.tpdo1.position, x.tpdo2.velocity), (222, 22));
        assert_eq!(x.end(), (true, 0));
        assert_eq!(x.counters.late, 2);
        assert_eq!(x.counters.lost, 0);
        assert_eq!(x.counters.missed, 2);
        // The reference this replaces: classifying by when the frame was read (in the
        // wait) took cycle 1's answer as cycle 2's sample.
        let mut naive = Exchange::new(5);
        sync_at(&mut naive, t0, 2050);
        naive.on_frame(&late1, us(t0, 2300)); // read time, not arrival
        assert_eq!(naive.tpdo1.position, 111);
    }

    /// A stale duplicate that arrived before the SYNC (nothing was missing) is ignored,
    /// not counted late, and does not fill the cycle.
    #[test]
    fn an_answer_from_before_the_sync_is_never_this_cycles() {
        let t0 = Instant::now();
        let mut x = Exchange::new(5);
        sync_at(&mut x, t0, 1000);
        let [a, b] = answer(5, 5);
        assert_eq!(x.on_frame(&a, us(t0, 999)), Event::Ignored);
        assert_eq!(x.on_frame(&b, us(t0, 999)), Event::Ignored);
        assert!(!x.complete());
        assert_eq!(x.counters.late, 0);
        assert_eq!(x.on_frame(&a, us(t0, 1000)), Event::Feedback);
    }
}

//! The sans-I/O core of one cycle: builds the frames to send and classifies every
//! received frame. The blocking layer ([`super::Drive::cycle`]) only moves frames and
//! time in and out. No allocation.

use canopen_rs::EmergencyMessage;
use flexid_can::CanFrame;

use crate::cob::{self, Cob};
use crate::drive::Counters;
use crate::pdo::{pack_rpdo1, Tpdo1, Tpdo2};

const GOT1: u8 = 1;
const GOT2: u8 = 2;
const ALL: u8 = GOT1 | GOT2;

/// When a frame was received.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Before this cycle's SYNC: anything still queued from the previous cycle.
    Drain,
    /// After this cycle's SYNC, before its deadline.
    Wait,
}

/// What a received frame meant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// This cycle's TPDO1 or TPDO2 (stored).
    Feedback,
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
            consecutive_missed: 0,
            tpdo1: Tpdo1::default(),
            tpdo2: Tpdo2::default(),
            counters: Counters::default(),
        }
    }

    /// Ends the drain phase (the previous cycle's missing TPDOs not seen by now are
    /// lost) and returns this cycle's RPDO1 and SYNC, in sending order.
    pub fn begin(&mut self, controlword: u16, torque_permille: i16) -> [CanFrame; 2] {
        self.counters.lost += self.missing_prev.count_ones() as u64;
        self.missing_prev = 0;
        self.got = 0;
        let rpdo = CanFrame::standard(
            cob::rpdo(1, self.node),
            &pack_rpdo1(controlword, torque_permille),
        )
        .expect("4 bytes on an 11-bit id");
        let sync = CanFrame::standard(cob::SYNC, &[]).expect("0 bytes on an 11-bit id");
        [rpdo, sync]
    }

    /// Whether all of this cycle's TPDOs are in.
    pub fn complete(&self) -> bool {
        self.got == ALL
    }

    /// Ends the wait (deadline reached or complete): counts the missing TPDOs;
    /// returns whether the cycle was complete and the consecutive incomplete cycles.
    pub fn end(&mut self) -> (bool, u32) {
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

    /// Classifies one received frame (never panics).
    pub fn on_frame(&mut self, frame: &CanFrame, phase: Phase) -> Event {
        let node = self.node;
        let ev = match cob::classify(frame) {
            Cob::Tpdo(n @ 1..=2, id) if id == node => {
                let bit = if n == 1 { GOT1 } else { GOT2 };
                match phase {
                    Phase::Drain => {
                        if self.missing_prev & bit != 0 {
                            self.missing_prev &= !bit;
                            self.counters.late += 1;
                        }
                        // a late or duplicate TPDO carries stale data: not used
                        return Event::Ignored;
                    }
                    Phase::Wait if self.got & bit != 0 => Event::Ignored, // duplicate
                    Phase::Wait => {
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

    fn f(id: u16, d: &[u8]) -> CanFrame {
        CanFrame::standard(id, d).unwrap()
    }

    #[test]
    fn classifies_and_counts() {
        let mut x = Exchange::new(3);
        let [rpdo, sync] = x.begin(0x000F, -2);
        assert_eq!(rpdo, f(0x203, &[0x0F, 0x00, 0xFE, 0xFF]));
        assert_eq!(sync, f(0x080, &[]));
        assert_eq!(
            x.on_frame(&f(0x183, &[0x27, 0, 1, 0, 0, 0, 5, 0]), Phase::Wait),
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
        assert_eq!(
            x.on_frame(&f(0x283, &[1, 2]), Phase::Wait),
            Event::Malformed
        );
        assert_eq!(x.on_frame(&f(0x184, &[0; 8]), Phase::Wait), Event::Ignored);
        assert_eq!(
            x.on_frame(&f(0x083, &[0; 3]), Phase::Wait),
            Event::Malformed
        );
        assert_eq!(x.on_frame(&f(0x083, &[0; 8]), Phase::Wait), Event::Ignored); // reset
        assert_eq!(
            x.on_frame(&f(0x703, &[0x7F]), Phase::Wait),
            Event::NmtState(0x7F)
        );
        assert!(!x.complete());
        assert_eq!(x.end(), (false, 1));
        // TPDO2 arrives late, during the next drain
        assert_eq!(x.on_frame(&f(0x283, &[0; 4]), Phase::Drain), Event::Ignored);
        x.begin(0x000F, 0);
        assert_eq!(x.counters.missed, 1);
        assert_eq!(x.counters.late, 1);
        assert_eq!(x.counters.lost, 0);
        assert_eq!(x.end(), (false, 2));
        x.begin(0x000F, 0);
        assert_eq!(x.counters.lost, 2);
        assert_eq!(x.counters.malformed, 2);
    }
}

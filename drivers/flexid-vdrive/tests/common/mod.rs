//! Test helpers: a drive on the default plant with injected time, hand-written frames.

#![allow(dead_code)]

use std::time::Duration;

use flexid_can::CanFrame;
use flexid_vdrive::{linear_drive, ClockMode, DrivePlant, LinearChain, VirtualDrive};

pub const NODE: u16 = 5;

pub fn ms(v: u64) -> Duration {
    Duration::from_millis(v)
}

pub fn frame(cob: u16, data: &[u8]) -> CanFrame {
    CanFrame::standard(cob, data).unwrap()
}

/// The default plant (embedded SCARA shoulder) with an optional extra `[drive]` text.
pub fn plant(drive_toml: &str) -> DrivePlant {
    let text = format!(
        "{}\n[drive]\n{drive_toml}\n",
        flexid_core::plant::DEFAULT_PLANT
    );
    DrivePlant::parse(&text, "test plant").unwrap()
}

/// A drive under test with its own clock.
pub struct Dut {
    pub drive: VirtualDrive<LinearChain>,
    pub now: Duration,
}

impl Dut {
    /// Default plant, powered on (boot-up frame checked).
    pub fn new() -> Self {
        Self::with(&plant(""))
    }

    pub fn with(p: &DrivePlant) -> Self {
        let drive = linear_drive(p, ClockMode::LockStep).unwrap();
        Self::from_drive(drive)
    }

    pub fn from_drive(mut drive: VirtualDrive<LinearChain>) -> Self {
        let out: Vec<CanFrame> = drive.power_on(Duration::ZERO).iter().copied().collect();
        assert_eq!(
            out,
            vec![frame(0x700 + drive.config().node_id as u16, &[0x00])]
        );
        Self {
            drive,
            now: Duration::ZERO,
        }
    }

    /// Sends one frame at the current time; the frames the drive answers with.
    pub fn send(&mut self, cob: u16, data: &[u8]) -> Vec<CanFrame> {
        self.drive
            .on_frame(&frame(cob, data), self.now)
            .iter()
            .copied()
            .collect()
    }

    /// An SDO request (8 bytes) to node 5; the single response's 8 bytes.
    pub fn sdo(&mut self, req: [u8; 8]) -> [u8; 8] {
        let out = self.send(0x600 + NODE, &req);
        assert_eq!(out.len(), 1, "one SDO response to {req:02X?}: {out:?}");
        assert_eq!(out[0].id().raw(), 0x580 + NODE as u32);
        out[0].data().try_into().unwrap()
    }

    /// SDO download, expecting the plain confirmation `60 ii ii ss 00 00 00 00`.
    pub fn sdo_ok(&mut self, req: [u8; 8]) {
        let r = self.sdo(req);
        assert_eq!(r, [0x60, req[1], req[2], req[3], 0, 0, 0, 0], "{req:02X?}");
    }

    pub fn start(&mut self) {
        assert!(self.send(0x000, &[0x01, NODE as u8]).is_empty());
    }

    /// RPDO1 (default mapping): controlword, target torque [per-mille].
    pub fn rpdo(&mut self, cw: u16, torque: i16) -> Vec<CanFrame> {
        let [c0, c1] = cw.to_le_bytes();
        let [t0, t1] = torque.to_le_bytes();
        self.send(0x200 + NODE, &[c0, c1, t0, t1])
    }

    /// A SYNC; the frames sent.
    pub fn sync(&mut self) -> Vec<CanFrame> {
        self.send(0x080, &[])
    }

    /// Advances the clock by `d`, calling `tick` every millisecond; the frames produced.
    pub fn run_for(&mut self, d: Duration) -> Vec<(Duration, CanFrame)> {
        let end = self.now + d;
        let mut got = Vec::new();
        while self.now < end {
            self.now += ms(1);
            for f in self.drive.tick(self.now).iter() {
                got.push((self.now, *f));
            }
        }
        got
    }

    /// Statusword from a SYNC's TPDO1 (default mapping).
    pub fn sync_statusword(&mut self) -> u16 {
        let out = self.sync();
        let t1 = out
            .iter()
            .find(|f| f.id().raw() == 0x180 + NODE as u32)
            .expect("TPDO1");
        u16::from_le_bytes([t1.data()[0], t1.data()[1]])
    }
}

/// Keeps 239.0.0.0/8 on `lo` ([`flexid_can::keep_multicast_on_loopback`]); false (skip)
/// when the group would leave through another interface.
pub fn loopback_multicast() -> bool {
    match flexid_can::keep_multicast_on_loopback(std::net::Ipv4Addr::new(239, 74, 163, 2)) {
        Ok(()) => true,
        Err(msg) => {
            skip(&msg);
            false
        }
    }
}

/// A test that cannot run here says why and passes, except in CI (`CI=true`), where the
/// project's own scripts set everything up and a skip would hide a broken set-up.
pub fn skip(why: &str) {
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("CI=true and this test cannot run: {why}");
    }
    eprintln!("skipped: {why}");
}

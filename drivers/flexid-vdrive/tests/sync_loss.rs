//! SYNC-loss supervision (issue 16, item 12): a drive in Operation enabled whose master
//! stops sending SYNC removes the torque within 3 SYNC periods and sends an EMCY.

mod common;
use std::time::Duration;

use common::*;
use flexid_vdrive::{linear_drive, ClockMode, FaultKind, State};

/// The default plant runs at 2 kHz: 0x1006 = 500 µs.
const PERIOD: Duration = Duration::from_micros(500);

fn enabled_realtime(drive_toml: &str) -> Dut {
    let drive = linear_drive(&plant(drive_toml), ClockMode::RealTime).unwrap();
    let mut d = Dut::from_drive(drive);
    // The master declares its cycle: 0x1006 = 500 µs.
    d.sdo_ok([0x23, 0x06, 0x10, 0x00, 0xF4, 0x01, 0x00, 0x00]);
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x0007, 0);
    d.rpdo(0x000F, 0);
    assert_eq!(d.drive.state(), State::OperationEnabled);
    d
}

/// SYNCs every period for `n` cycles at torque `permille`, ticking in between.
fn run_cycles(d: &mut Dut, n: usize, permille: i16) -> Vec<flexid_can::CanFrame> {
    let mut got = Vec::new();
    for _ in 0..n {
        d.rpdo(0x000F, permille);
        got.extend(d.sync());
        let next = d.now + PERIOD;
        while d.now < next {
            d.now += Duration::from_micros(50);
            got.extend(d.drive.tick(d.now).iter().copied());
        }
    }
    got
}

#[test]
fn a_lost_master_leaves_no_torque_after_3_sync_periods() {
    let mut d = enabled_realtime("");
    let frames = run_cycles(&mut d, 20, 1000);
    assert!(
        frames.iter().all(|f| f.id().raw() != 0x085),
        "no EMCY while SYNC comes every period: {frames:?}"
    );
    assert_eq!(d.drive.applied_torque_nm(), 1.0);
    // The master dies right after its last SYNC.
    d.rpdo(0x000F, 1000);
    d.sync();
    let last_sync = d.now;
    let mut emcy = None;
    let mut torque_off = None;
    while d.now < last_sync + 10 * PERIOD {
        d.now += Duration::from_micros(10);
        for f in d.drive.tick(d.now).iter() {
            if f.id().raw() == 0x085 && emcy.is_none() {
                emcy = Some((d.now, *f));
            }
        }
        if torque_off.is_none() && d.drive.applied_torque_nm() == 0.0 {
            torque_off = Some(d.now);
        }
    }
    let off = torque_off.expect("the torque was never removed");
    assert!(
        off - last_sync <= 3 * PERIOD,
        "torque removed {:?} after the last SYNC (3 periods: {:?})",
        off - last_sync,
        3 * PERIOD
    );
    let (at, f) = emcy.expect("an EMCY for the lost SYNC");
    assert!(at - last_sync <= 3 * PERIOD);
    // EMCY 0x8700 (CiA 402 "sync controller"), error register generic | communication.
    assert_eq!(f.data(), &[0x00, 0x87, 0x11, 0, 0, 0, 0, 0]);
    assert_eq!(d.drive.fault(), Some(FaultKind::SyncLost));
    assert_eq!(d.drive.state(), State::Fault);
}

#[test]
fn sync_loss_supervision_is_configurable_and_can_be_off() {
    // 5 cycles: not yet at 4 periods, tripped by 6.
    let mut d = enabled_realtime("sync_loss_cycles = 5");
    run_cycles(&mut d, 5, 500);
    d.sync();
    let last = d.now;
    d.now = last + 4 * PERIOD;
    assert!(d.drive.tick(d.now).is_empty());
    assert_eq!(d.drive.applied_torque_nm(), 0.5);
    d.now = last + 6 * PERIOD;
    assert_eq!(d.drive.tick(d.now).len(), 1);
    assert_eq!(d.drive.applied_torque_nm(), 0.0);

    let mut d = enabled_realtime("sync_loss_cycles = 0");
    run_cycles(&mut d, 5, 500);
    d.now += 100 * PERIOD;
    assert!(d.drive.tick(d.now).is_empty());
    assert_eq!(d.drive.state(), State::OperationEnabled);
}

/// A master that never wrote 0x1006 has not told the drive its SYNC period (python's
/// canopen runs SYNC at whatever rate its script chose): nothing is supervised, the
/// heartbeat consumer is what watches such a master.
#[test]
fn an_undeclared_period_is_not_supervised() {
    let drive = linear_drive(&plant(""), ClockMode::RealTime).unwrap();
    let mut d = Dut::from_drive(drive);
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x000F, 500);
    d.sync();
    d.now += 100 * PERIOD;
    assert!(d.drive.tick(d.now).is_empty());
    assert_eq!(d.drive.applied_torque_nm(), 0.5);
}

#[test]
fn supervision_starts_with_the_first_sync_in_operation_enabled() {
    // Enabled by RPDO but no SYNC yet: nothing to supervise.
    let mut d = enabled_realtime("");
    d.now += 100 * PERIOD;
    assert!(d.drive.tick(d.now).is_empty());
    assert_eq!(d.drive.state(), State::OperationEnabled);
    // SYNCs in Switch on disabled do not arm it either.
    d.rpdo(0x0000, 0);
    d.sync();
    d.now += 100 * PERIOD;
    assert!(d.drive.tick(d.now).is_empty());
    d.rpdo(0x0006, 0);
    d.rpdo(0x000F, 0);
    assert_eq!(d.drive.state(), State::OperationEnabled);
    d.now += 100 * PERIOD;
    assert!(d.drive.tick(d.now).is_empty(), "an old SYNC does not count");
    assert_eq!(d.drive.state(), State::OperationEnabled);
}

#[test]
fn the_next_deadline_includes_the_sync_supervision() {
    let mut d = enabled_realtime("");
    run_cycles(&mut d, 3, 100);
    d.sync();
    let last = d.now;
    let due = d
        .drive
        .next_deadline()
        .expect("a wake-up for the supervision");
    assert!(
        due > last && due <= last + 3 * PERIOD,
        "{due:?} after {last:?}"
    );
}

/// The done-when of issue 16 on a bus: the real-time drive behind its [`Runner`], a
/// master that enables it, runs 2 ms SYNC cycles at 1 N m and dies. The EMCY comes, and
/// the torque is gone, within 3 SYNC periods of the first SYNC that did not come.
#[test]
fn on_a_bus_a_dead_master_leaves_no_torque_within_3_sync_periods() {
    use flexid_can::{CanBus, InprocBus};
    use flexid_vdrive::Runner;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use std::time::Instant;

    let drive = linear_drive(&plant(""), ClockMode::RealTime).unwrap();
    let mut master = InprocBus::new("sync-loss");
    let bus = master.handle();
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    let th = std::thread::spawn(move || {
        let mut r = Runner::new(bus, drive);
        r.run(&stop2).unwrap();
        r
    });
    let wait_for = |m: &mut InprocBus, cob: u32| loop {
        let r = m
            .recv_timeout(Duration::from_secs(5))
            .unwrap()
            .unwrap_or_else(|| panic!("no 0x{cob:03X} within 5 s"));
        if r.frame.id().raw() == cob {
            return r;
        }
    };
    wait_for(&mut master, 0x705);
    // 0x1006 = 2000 µs: the cycle the master runs.
    let period = Duration::from_millis(2);
    master
        .send(&frame(
            0x605,
            &[0x23, 0x06, 0x10, 0x00, 0xD0, 0x07, 0x00, 0x00],
        ))
        .unwrap();
    wait_for(&mut master, 0x585);
    master.send(&frame(0x000, &[0x01, 0x05])).unwrap();
    for cw in [0x06u8, 0x07, 0x0F] {
        master.send(&frame(0x205, &[cw, 0, 0, 0])).unwrap();
    }
    let mut last_sync = Instant::now();
    let t0 = Instant::now();
    for k in 1..=50u32 {
        master
            .send(&frame(0x205, &[0x0F, 0x00, 0xE8, 0x03]))
            .unwrap(); // 1000 per mille
        last_sync = Instant::now();
        master.send(&frame(0x080, &[])).unwrap();
        let next = t0 + period * k;
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    // The master is gone; the first missing SYNC was due one period after the last.
    let emcy = wait_for(&mut master, 0x085);
    assert_eq!(emcy.frame.data()[..3], [0x00, 0x87, 0x11]);
    let lost_at = last_sync + period;
    let after = emcy.timestamp.saturating_duration_since(lost_at);
    assert!(
        after <= 3 * period,
        "EMCY {after:?} after the first missing SYNC (3 periods: {:?})",
        3 * period
    );
    stop.store(true, Ordering::Relaxed);
    let r = th.join().unwrap();
    assert_eq!(r.drive().applied_torque_nm(), 0.0);
    assert_eq!(r.drive().fault(), Some(FaultKind::SyncLost));
}

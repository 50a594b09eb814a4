//! Test doubles: a scripted drive (recorded request/response frames) and a simulated
//! CiA 402 drive with a trivial integrator, both on `InprocBus`.
#![allow(dead_code)]

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use flexid_can::{CanBus, CanFrame, InprocBus};
use flexid_canopen::cia402::{device_transition, Controlword, State};

/// A frame as (11-bit id, data).
pub type Raw = (u16, Vec<u8>);

pub fn raw(id: u16, d: &[u8]) -> Raw {
    (id, d.to_vec())
}

fn to_raw(f: &CanFrame) -> Raw {
    (f.id().raw() as u16, f.data().to_vec())
}

fn frame(r: &Raw) -> CanFrame {
    CanFrame::standard(r.0, &r.1).unwrap()
}

/// Runs a script: for each step, waits for the next frame from the master, records it,
/// and if it is the expected one sends the responses. Stops at the first unexpected
/// frame, at the end of the script, or when nothing comes within `idle`. Returns every
/// frame received, in order.
pub fn scripted_drive(
    mut bus: InprocBus,
    script: Vec<(Raw, Vec<Raw>)>,
    idle: Duration,
) -> JoinHandle<Vec<Raw>> {
    std::thread::spawn(move || {
        let mut got = Vec::new();
        for (expect, responses) in script {
            let Ok(Some(r)) = bus.recv_timeout(idle) else {
                break;
            };
            let rx = to_raw(&r.frame);
            got.push(rx.clone());
            if rx != expect {
                break;
            }
            for resp in &responses {
                bus.send(&frame(resp)).unwrap();
            }
        }
        // anything more the master sends (should be nothing)
        while let Ok(Some(r)) = bus.recv_timeout(Duration::from_millis(50)) {
            got.push(to_raw(&r.frame));
        }
        got
    })
}

/// Behaviour switches of the simulated drive.
#[derive(Debug, Clone, Default)]
pub struct SimOptions {
    /// SYNC numbers (counted from 0 after NMT start) at which TPDO2 is not sent.
    pub drop_tpdo2: HashSet<u64>,
    /// SYNC numbers at which TPDO1 is sent `late_by` after the SYNC.
    pub late_tpdo1: HashSet<u64>,
    /// Delay of late TPDO1s.
    pub late_by: Duration,
    /// SYNC number at which an EMCY (0x2310, register 0x03, data 1..5) is sent and the
    /// drive faults.
    pub emcy_at: Option<u64>,
    /// SYNC numbers before whose TPDOs garbage frames are sent.
    pub garbage_at: HashSet<u64>,
    /// Value 0x6061 shows after 0x6060 is written (None: the written value).
    pub mode_display: Option<i8>,
    /// The drive starts in Fault (fault cleared, so a reset works).
    pub start_in_fault: bool,
    /// Vendor-id in 0x1018:1 (None: flexid-vdrive's); the sim also has 0x608F = 10000
    /// increments / 1 revolution and 0x6076 = 2500 mN m for the generic profile.
    pub vendor: Option<u32>,
    /// Every controlword received in RPDO1, in order.
    pub cw_log: Arc<Mutex<Vec<u16>>>,
}

/// Sim parameters: 2^20 increments/rev, rated torque 1 N m, inertia J.
pub const INC_PER_REV: f64 = 1048576.0;
pub const INERTIA: f64 = 0.01; // kg m^2

/// A simulated CiA 402 drive (node `node`, flexid-vdrive identity) answering expedited
/// SDOs from a small object dictionary, NMT, and SYNC with TPDO1/TPDO2 from a
/// double-integrator plant stepped `dt` per SYNC. Stops when `stop` is set.
pub fn sim_drive(
    mut bus: InprocBus,
    node: u8,
    dt: f64,
    opts: SimOptions,
    stop: Arc<AtomicBool>,
) -> JoinHandle<HashMap<(u16, u8), u32>> {
    std::thread::spawn(move || {
        let mut od: HashMap<(u16, u8), (u8, u32)> = HashMap::new(); // (size, value)
        od.insert((0x1000, 0), (4, 0x0002_0192));
        od.insert((0x1018, 1), (4, opts.vendor.unwrap_or(0x0000_0F1D)));
        od.insert((0x608F, 1), (4, 10_000));
        od.insert((0x608F, 2), (4, 1));
        od.insert((0x6076, 0), (4, 2500));
        od.insert((0x1018, 2), (4, 0x0000_0402));
        od.insert((0x1018, 3), (4, 0x0001_0000));
        od.insert((0x1018, 4), (4, 42));
        od.insert((0x6502, 0), (4, 0x388));
        od.insert((0x6061, 0), (1, 0));
        od.insert((0x603F, 0), (2, 0));
        od.insert((0x1001, 0), (1, 0));
        let mut written: HashMap<(u16, u8), u32> = HashMap::new();
        let mut operational = false;
        let mut state = if opts.start_in_fault {
            State::Fault
        } else {
            State::SwitchOnDisabled
        };
        let mut fault = false;
        let mut cw = Controlword(0);
        let mut prev_cw = Controlword(0);
        let mut torque: i16 = 0;
        let (mut pos, mut vel) = (0.0f64, 0.0f64);
        let mut sync_n: u64 = 0;
        let sdo_tx = 0x580 + node as u16;
        let send = |bus: &mut InprocBus, id: u16, d: &[u8]| {
            let _ = bus.send(&CanFrame::standard(id, d).unwrap());
        };
        while !stop.load(Ordering::Relaxed) {
            let Ok(Some(r)) = bus.recv_timeout(Duration::from_millis(20)) else {
                continue;
            };
            let f = r.frame;
            let id = f.id().raw() as u16;
            let d = f.data();
            if id == 0x000 && d.len() == 2 && (d[1] == node || d[1] == 0) {
                match d[0] {
                    0x81 | 0x82 => {
                        operational = false;
                        send(&mut bus, 0x700 + node as u16, &[0x00]);
                    }
                    0x01 => {
                        operational = true;
                        sync_n = 0;
                    }
                    0x80 | 0x02 => operational = false,
                    _ => {}
                }
            } else if id == 0x600 + node as u16 && d.len() == 8 {
                let index = u16::from_le_bytes([d[1], d[2]]);
                let sub = d[3];
                let mux = [d[1], d[2], d[3]];
                match d[0] {
                    0x40 => match od.get(&(index, sub)) {
                        Some(&(size, v)) => {
                            let n = 4 - size;
                            let b = v.to_le_bytes();
                            send(
                                &mut bus,
                                sdo_tx,
                                &[
                                    0x43 | (n << 2),
                                    mux[0],
                                    mux[1],
                                    mux[2],
                                    b[0],
                                    b[1],
                                    b[2],
                                    b[3],
                                ],
                            );
                        }
                        None => send(
                            &mut bus,
                            sdo_tx,
                            &[0x80, mux[0], mux[1], mux[2], 0x00, 0x00, 0x02, 0x06],
                        ),
                    },
                    c if c & 0xE3 == 0x23 => {
                        let size = 4 - ((c >> 2) & 3);
                        let mut b = [0u8; 4];
                        b[..size as usize].copy_from_slice(&d[4..4 + size as usize]);
                        let v = u32::from_le_bytes(b);
                        written.insert((index, sub), v);
                        if index == 0x6060 {
                            let shown = opts.mode_display.unwrap_or(v as u8 as i8);
                            od.insert((0x6061, 0), (1, shown as u8 as u32));
                        }
                        send(
                            &mut bus,
                            sdo_tx,
                            &[0x60, mux[0], mux[1], mux[2], 0, 0, 0, 0],
                        );
                    }
                    _ => send(
                        &mut bus,
                        sdo_tx,
                        &[0x80, mux[0], mux[1], mux[2], 0x01, 0x00, 0x04, 0x05],
                    ),
                }
            } else if id == 0x200 + node as u16 && d.len() == 4 && operational {
                cw = Controlword(u16::from_le_bytes([d[0], d[1]]));
                opts.cw_log.lock().unwrap().push(cw.0);
                torque = i16::from_le_bytes([d[2], d[3]]);
            } else if id == 0x080 && d.is_empty() && operational {
                let n = sync_n;
                sync_n += 1;
                if opts.emcy_at == Some(n) {
                    fault = true;
                    send(
                        &mut bus,
                        0x080 + node as u16,
                        &[0x10, 0x23, 0x03, 1, 2, 3, 4, 5],
                    );
                }
                state = device_transition(state, cw.effective(prev_cw), fault);
                prev_cw = cw;
                let applied = if state == State::OperationEnabled {
                    torque
                } else {
                    0
                };
                let acc = applied as f64 / 1000.0 * 1.0 / INERTIA;
                vel += acc * dt;
                pos += vel * dt;
                if opts.garbage_at.contains(&n) {
                    send(&mut bus, 0x180 + node as u16, &[0x27, 0x00, 0x01]); // short TPDO1
                    send(&mut bus, 0x7E4, &[0x11, 0, 0, 0, 0, 0, 0, 0]); // LSS response
                    send(&mut bus, sdo_tx, &[0xFF]); // garbage SDO
                    send(
                        &mut bus,
                        0x081 + node as u16,
                        &[0x00, 0x10, 0x01, 0, 0, 0, 0, 0],
                    ); // EMCY of another node
                    let _ = bus.send(&CanFrame::extended(0x180 + node as u32, &[0; 8]).unwrap());
                    send(&mut bus, 0x700 + node as u16, &[0x05, 0x05]); // 2-byte heartbeat
                }
                let sw = state.status_bits()
                    | if state == State::OperationEnabled {
                        0x0210
                    } else {
                        0x0200
                    };
                let p = (pos * INC_PER_REV / std::f64::consts::TAU).round() as i32;
                let v = (vel * INC_PER_REV / std::f64::consts::TAU).round() as i32;
                let s = sw.to_le_bytes();
                let pb = p.to_le_bytes();
                let tb = applied.to_le_bytes();
                let t1 = [s[0], s[1], pb[0], pb[1], pb[2], pb[3], tb[0], tb[1]];
                if opts.late_tpdo1.contains(&n) {
                    std::thread::sleep(opts.late_by);
                }
                send(&mut bus, 0x180 + node as u16, &t1);
                if !opts.drop_tpdo2.contains(&n) {
                    send(&mut bus, 0x280 + node as u16, &v.to_le_bytes());
                }
            }
        }
        written
    })
}

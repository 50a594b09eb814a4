//! A segment: emulated SubDevices in ring order, processing a frame in place exactly as a
//! line of real ESCs does. Each SubDevice handles every PDU (addressing, data, working
//! counter) and passes the frame on; the last one loops it back, and the frame returns with
//! the locally administered bit set in its source MAC.
//!
//! Time: the segment has a clock (ns) the caller sets or advances. A frame reaches
//! SubDevice `i` after `i` hops of [`Segment::hop_ns`] and returns through its port 1 after
//! passing the SubDevices behind it; the DC latches see these times in each SubDevice's
//! local clock.
//!
//! The application behind a SubDevice (a drive, [`crate::servo`]) is an [`Application`]
//! the segment calls around every frame that carries process data (a logical command):
//! [`Application::latch_inputs`] as the frame arrives, before the ESC copies the mapped
//! inputs into its buffer, and [`Application::apply_outputs`] after the frame has passed and
//! the outputs reached the dictionary. This is the lock-step clock: one process-data
//! exchange is one drive cycle.
//!
//! SYNC0: every SubDevice whose SYNC0 unit is active generates pulses on its system time;
//! [`Segment::run_sync0_until`] hands each pulse due up to a segment time to the
//! application ([`Application::sync0`]), in time order with the frames: [`Segment::process`]
//! runs the pulses due before the frame arrives first. An application on the SYNC0 clock
//! (the servo's [`crate::servo::ServoClock::Sync0`]) latches its process data there; a
//! lock-step one ignores the pulses. Between frames a clock thread
//! ([`crate::sync0_clock`]) runs them at their time.

use crate::esc::al::AlState;
use crate::esc::SubDevice;
use crate::frame::{mark_forwarded, Addressing, FrameError, FrameLayout};

/// The application behind a SubDevice, run in lock-step with the process-data exchange.
///
/// Timing of a real drive with "input latch before the frame, outputs applied after it"
/// (SYNC0 shifted to the frame): the inputs the frame carries are sampled just before it
/// passes, its outputs act just after.
pub trait Application: Send + std::fmt::Debug {
    /// A process-data frame reaches the SubDevice (SAFE-OP or OP): sample and write the
    /// input objects into `device`'s dictionary; the ESC maps them into this frame.
    fn latch_inputs(&mut self, device: &mut SubDevice);
    /// The process-data frame has passed (OP): the output objects are in `device`'s
    /// dictionary; act on them for one cycle.
    fn apply_outputs(&mut self, device: &mut SubDevice);
    /// A SYNC0 pulse of `device`'s DC unit (SAFE-OP or OP). Lock-step applications ignore
    /// it (the default).
    fn sync0(&mut self, device: &mut SubDevice) {
        let _ = device;
    }
    /// The application's cycle counters (all zero for an application that keeps none).
    fn stats(&self) -> CycleStats {
        CycleStats::default()
    }
}

/// Cycle counters of an [`Application`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CycleStats {
    /// Inputs latched (lock-step: process-data frames in SAFE-OP or OP; SYNC0: pulses in
    /// SAFE-OP or OP).
    pub latches: u64,
    /// Plant cycles stepped (in OP).
    pub cycles: u64,
    /// SYNC0 pulses seen (SAFE-OP or OP).
    pub pulses: u64,
    /// SYNC0 clock, OP: pulses with no process-data frame since the one before (the
    /// outputs held: a missed cycle).
    pub missed: u64,
    /// SYNC0 clock, OP: frames whose outputs were overwritten by a later frame before a
    /// pulse applied them (two frames in one cycle).
    pub overwritten: u64,
    /// Longest run of consecutive missed cycles.
    pub longest_missed_run: u64,
}

/// SubDevices in ring order and the segment clock.
#[derive(Debug, Default)]
pub struct Segment {
    devices: Vec<SubDevice>,
    /// The application behind each SubDevice (same positions as `devices`).
    applications: Vec<Option<Box<dyn Application>>>,
    time_ns: u64,
    /// Delay from one SubDevice's port 0 to the next one's (forwarding and cable), ns.
    pub hop_ns: u64,
    frames: u64,
}

/// What one frame did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameReport {
    /// PDUs in the frame.
    pub pdus: usize,
    /// SubDevices the frame passed.
    pub subdevices: usize,
}

impl Segment {
    /// An empty segment; hops of 1 us.
    pub fn new() -> Self {
        Self {
            devices: Vec::new(),
            applications: Vec::new(),
            time_ns: 0,
            hop_ns: 1_000,
            frames: 0,
        }
    }

    /// Appends a SubDevice at the end of the line.
    pub fn push(&mut self, mut device: SubDevice) {
        if let Some(last) = self.devices.last_mut() {
            last.set_port1_linked(true);
        }
        device.set_port1_linked(false);
        self.devices.push(device);
        self.applications.push(None);
    }

    /// Appends a SubDevice with the application behind it.
    pub fn push_with(&mut self, device: SubDevice, application: Box<dyn Application>) {
        self.push(device);
        if let Some(slot) = self.applications.last_mut() {
            *slot = Some(application);
        }
    }

    /// Takes the SubDevice at `position` off the line (a cable pulled, a SubDevice lost):
    /// the ones behind it move up, frames no longer reach it.
    pub fn remove(&mut self, position: usize) -> Option<SubDevice> {
        if position >= self.devices.len() {
            return None;
        }
        self.applications.remove(position);
        let device = self.devices.remove(position);
        if let Some(last) = self.devices.last_mut() {
            last.set_port1_linked(false);
        }
        Some(device)
    }

    /// The application behind the SubDevice at `position`.
    pub fn application(&self, position: usize) -> Option<&dyn Application> {
        self.applications.get(position)?.as_deref()
    }

    pub fn len(&self) -> usize {
        self.devices.len()
    }

    pub fn is_empty(&self) -> bool {
        self.devices.is_empty()
    }

    pub fn subdevice(&self, position: usize) -> Option<&SubDevice> {
        self.devices.get(position)
    }

    pub fn subdevice_mut(&mut self, position: usize) -> Option<&mut SubDevice> {
        self.devices.get_mut(position)
    }

    pub fn subdevices(&self) -> &[SubDevice] {
        &self.devices
    }

    /// Segment time, ns.
    pub fn time_ns(&self) -> u64 {
        self.time_ns
    }

    /// Sets segment time (ns); it never goes back.
    pub fn set_time_ns(&mut self, ns: u64) {
        self.time_ns = self.time_ns.max(ns);
    }

    /// Frames processed.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Hands every SYNC0 pulse due up to segment time `segment_ns` (inclusive) to the
    /// application behind its SubDevice (SAFE-OP or OP); sets the segment time to it.
    /// Returns the pulses handed over.
    pub fn run_sync0_until(&mut self, segment_ns: u64) -> u64 {
        self.set_time_ns(segment_ns);
        let now = self.time_ns;
        let mut pulses = 0;
        for (device, application) in self.devices.iter_mut().zip(self.applications.iter_mut()) {
            let due = device.take_sync0_pulses(now);
            pulses += due;
            let Some(app) = application.as_deref_mut() else {
                continue;
            };
            if device.al_state() < AlState::SafeOp {
                continue;
            }
            for _ in 0..due {
                app.sync0(device);
            }
        }
        pulses
    }

    /// Segment time of the next SYNC0 pulse of any SubDevice after the segment time, ns
    /// (`None` while no SYNC0 unit is active).
    pub fn next_sync0_ns(&self) -> Option<u64> {
        self.devices
            .iter()
            .filter_map(|d| d.next_sync0_ns(self.time_ns))
            .min()
    }

    /// Passes `frame` (a whole Ethernet frame) through every SubDevice in order, in place,
    /// after the SYNC0 pulses due before it ([`Segment::run_sync0_until`] at the segment
    /// time). A frame that is not a valid EtherCAT frame is left untouched (a real segment
    /// would drop it).
    pub fn process(&mut self, frame: &mut [u8]) -> Result<FrameReport, FrameError> {
        let layout = FrameLayout::parse(frame)?;
        self.run_sync0_until(self.time_ns);
        let mut process_data = false;
        layout.for_each_pdu(frame, |pdu| {
            process_data |= pdu.command.addressing() == Addressing::Logical;
        });
        let n = self.devices.len() as u64;
        for (i, (device, application)) in self
            .devices
            .iter_mut()
            .zip(self.applications.iter_mut())
            .enumerate()
        {
            let i = i as u64;
            let arrival = self.time_ns + i * self.hop_ns;
            // Out to the end of the line and back: the frame returns through port 1 after
            // 2 (n - 1 - i) hops.
            let back = (i + 1 < n).then(|| arrival + 2 * (n - 1 - i) * self.hop_ns);
            device.check_watchdog(arrival);
            let mut application = application.as_deref_mut().filter(|_| process_data);
            if let Some(app) = &mut application {
                if device.al_state() >= AlState::SafeOp {
                    app.latch_inputs(device);
                }
            }
            device.begin_frame(arrival, back);
            layout.for_each_pdu(frame, |pdu| device.process_pdu(pdu));
            device.end_frame();
            if let Some(app) = &mut application {
                if device.al_state() == AlState::Op {
                    app.apply_outputs(device);
                }
            }
        }
        mark_forwarded(frame);
        self.frames += 1;
        Ok(FrameReport {
            pdus: layout.pdus,
            subdevices: self.devices.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::sii::Identity;
    use crate::esc::SubDeviceConfig;
    use crate::frame::tests::{build, pdu};
    use crate::frame::Command;

    fn line(n: usize) -> Segment {
        let mut s = Segment::new();
        for i in 0..n {
            let id = Identity {
                vendor_id: 0x0A1D,
                product_code: 0x10 + i as u32,
                revision: 1,
                serial: i as u32,
            };
            let config = SubDeviceConfig::servo_axis(id, &format!("AX{i}"));
            s.push(SubDevice::new(config).expect("valid SII"));
        }
        s
    }

    #[test]
    fn broadcast_read_counts_every_subdevice_and_marks_the_source_mac() {
        let mut s = line(3);
        let mut f = build(&[(Command::Brd, 0, &[0, 0])]);
        s.process(&mut f).expect("valid frame");
        // ESC type 0x11 ORed over three SubDevices; one count each.
        assert_eq!(pdu(&mut f, 0), (vec![0x11, 0x00], 3));
        assert_eq!(f[6], 0x12);
    }

    #[test]
    fn position_and_station_addressing_reach_one_subdevice() {
        let mut s = line(3);
        // APWR position 1 (address field -1) writes station address 0x1001.
        let mut f = build(&[(Command::Apwr, 0x0010_FFFF, &[0x01, 0x10])]);
        s.process(&mut f).expect("valid frame");
        assert_eq!(pdu(&mut f, 0).1, 1);
        assert_eq!(s.subdevice(1).map(SubDevice::station_address), Some(0x1001));
        assert_eq!(s.subdevice(0).map(SubDevice::station_address), Some(0));
        // FPRD of its product code through the EEPROM interface: request word 0x0A, read.
        let mut f = build(&[
            (
                Command::Fpwr,
                0x0502_1001,
                &[0x00, 0x01, 0x0A, 0x00, 0x00, 0x00],
            ),
            (Command::Fprd, 0x0508_1001, &[0; 4]),
            (Command::Fprd, 0x0508_1002, &[0; 4]),
        ]);
        s.process(&mut f).expect("valid frame");
        assert_eq!(pdu(&mut f, 0).1, 1);
        assert_eq!(pdu(&mut f, 1), (0x11u32.to_le_bytes().to_vec(), 1));
        assert_eq!(pdu(&mut f, 2), (vec![0; 4], 0));
    }

    #[test]
    fn read_write_and_read_multiple_write_count_as_specified() {
        let mut s = line(2);
        let mut f = build(&[(Command::Apwr, 0x0010_0000, &[0x00, 0x10])]);
        s.process(&mut f).expect("valid frame");
        // FPRW: the old value comes back, the new one is stored; read 1 + write 2.
        let mut f = build(&[(Command::Fprw, 0x0012_1000, &[0x34, 0x12])]);
        s.process(&mut f).expect("valid frame");
        assert_eq!(pdu(&mut f, 0), (vec![0, 0], 3));
        // FRMW: the addressed SubDevice reads, the other one writes.
        let mut f = build(&[(Command::Frmw, 0x0012_1000, &[0, 0])]);
        s.process(&mut f).expect("valid frame");
        assert_eq!(pdu(&mut f, 0), (vec![0x34, 0x12], 2));
        let alias = |i: usize| s.subdevice(i).map(|d| [d.memory()[0x12], d.memory()[0x13]]);
        assert_eq!(alias(1), Some([0x34, 0x12]));
        // Read-only registers keep their value.
        let mut f = build(&[(Command::Bwr, 0x0000_0000, &[0xFF])]);
        s.process(&mut f).expect("valid frame");
        assert_eq!(pdu(&mut f, 0).1, 2);
        assert_eq!(s.subdevice(0).map(|d| d.memory()[0]), Some(0x11));
    }

    #[test]
    fn receive_times_follow_the_line() {
        let mut s = line(3);
        s.set_time_ns(5_000);
        let mut f = build(&[(Command::Bwr, 0x0900_0000, &[0; 4])]);
        s.process(&mut f).expect("valid frame");
        let port = |i: usize, p: usize| {
            s.subdevice(i)
                .and_then(|d| crate::le::u32_at(d.memory(), 0x0900 + 4 * p))
        };
        // Arrival i hops after the first; back through port 1 after the devices behind.
        assert_eq!(port(0, 0), Some(5_000));
        assert_eq!(port(0, 1), Some(9_000));
        assert_eq!(port(1, 0), Some(6_000));
        assert_eq!(port(1, 1), Some(8_000));
        assert_eq!(port(2, 0), Some(7_000));
        assert_eq!(port(2, 1), Some(0));
    }

    /// An application that counts the SYNC0 pulses it is given.
    #[derive(Debug, Default)]
    struct Pulses(std::sync::Arc<std::sync::atomic::AtomicU64>);

    impl Application for Pulses {
        fn latch_inputs(&mut self, _: &mut SubDevice) {}
        fn apply_outputs(&mut self, _: &mut SubDevice) {}
        fn sync0(&mut self, _: &mut SubDevice) {
            self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }

    #[test]
    fn sync0_pulses_come_at_their_system_times_and_before_a_later_frame() {
        let mut s = line(2);
        let counted = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
        let id = Identity {
            vendor_id: 1,
            product_code: 2,
            revision: 3,
            serial: 4,
        };
        let device = SubDevice::new(SubDeviceConfig::servo_axis(id, "P")).expect("SII");
        s.push_with(device, Box::new(Pulses(counted.clone())));
        assert_eq!(s.next_sync0_ns(), None, "SYNC0 off");
        // SYNC0 every 250 us from system time 1 ms (the clocks start at 0, no offset).
        let mut f = build(&[
            (Command::Bwr, 0x09A0_0000, &250_000u32.to_le_bytes()),
            (Command::Bwr, 0x0990_0000, &1_000_000u64.to_le_bytes()),
            (Command::Bwr, 0x0981_0000, &[0x03]),
        ]);
        s.process(&mut f).expect("valid frame");
        assert_eq!(s.run_sync0_until(999_999), 0);
        assert_eq!(s.next_sync0_ns(), Some(1_000_000));
        // Three SubDevices, five pulses each up to 2 ms; the application is not called in
        // INIT.
        assert_eq!(s.run_sync0_until(2_000_000), 15);
        assert_eq!(s.run_sync0_until(2_000_000), 0, "each pulse once");
        assert_eq!(s.next_sync0_ns(), Some(2_250_000));
        assert_eq!(counted.load(std::sync::atomic::Ordering::Relaxed), 0);
        // A frame at 2.6 ms runs the pulse of 2.5 ms first.
        s.set_time_ns(2_600_000);
        let mut f = build(&[(Command::Brd, 0, &[0, 0])]);
        s.process(&mut f).expect("valid frame");
        assert_eq!(s.next_sync0_ns(), Some(2_750_000));
    }
}

//! An emulated EtherCAT SubDevice: its ESC (memory, registers, sync managers, FMMUs, DC,
//! EEPROM interface) and the application behind it (AL state machine, CoE object
//! dictionary, process data). Sans-I/O: [`SubDevice::process_pdu`] handles one datagram as
//! the frame passes; [`crate::Segment`] chains SubDevices.

pub mod al;
pub mod dc;
pub mod dictionary;
pub mod fmmu;
pub mod mailbox;
pub mod registers;
pub mod sii;
pub mod sync_manager;

use crate::frame::{Access, Addressing, Pdu};
use crate::le;
use al::{AlState, AlStateMachine, AlStatusCode, TransitionChecks};
use dc::{PortTimes, Sync0};
use dictionary::{MappedEntry, ObjectDictionary, RX_ASSIGN, TX_ASSIGN};
use fmmu::Fmmu;
use mailbox::Outcome;
use registers::EscInfo;
use sii::{Identity, MailboxArea, SiiDescription, SiiError, SiiInterface};
use sync_manager::{SmDirection, SmMode, SyncManager, STATUS_MAILBOX_FULL};

/// ESC memory: 4 KiB of registers and 8 KiB of process RAM, bytes.
pub const MEMORY_LEN: usize = 0x3000;

/// How to build an emulated SubDevice.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SubDeviceConfig {
    pub esc: EscInfo,
    pub sii: SiiDescription,
    /// The object dictionary the CoE mailbox serves.
    pub dictionary: ObjectDictionary,
    /// Shortest SYNC0 cycle the SubDevice accepts, ns (AL status 0x0036 below).
    pub min_sync0_cycle_ns: u32,
    /// Local clock at segment time 0, ns: SubDevices power up at different times.
    pub clock_origin_ns: u64,
}

impl SubDeviceConfig {
    /// A CiA 402 servo axis: ET1100-like ESC, 128-byte mailboxes at 0x1000/0x1080, outputs
    /// at 0x1100 and inputs at 0x1400, the cyclic synchronous torque mapping, SYNC0 down to
    /// 125 us (8 kHz).
    pub fn servo_axis(identity: Identity, name: &str) -> Self {
        Self {
            esc: EscInfo::et1100_like(),
            sii: SiiDescription {
                identity,
                name: name.into(),
                description: format!("{name} (flexid emulated CiA 402 axis)"),
                alias: 0,
                receive_mailbox: MailboxArea {
                    start: 0x1000,
                    len: 128,
                },
                send_mailbox: MailboxArea {
                    start: 0x1080,
                    len: 128,
                },
                outputs_start: 0x1100,
                inputs_start: 0x1400,
            },
            dictionary: ObjectDictionary::cia402_drive(&identity, name),
            min_sync0_cycle_ns: 125_000,
            clock_origin_ns: 0,
        }
    }
}

/// Where the current frame met this SubDevice, local time (ns).
#[derive(Debug, Clone, Copy, Default)]
struct FrameTimes {
    local: u64,
    port1: Option<u64>,
}

/// One emulated SubDevice.
#[derive(Debug, Clone)]
pub struct SubDevice {
    esc: EscInfo,
    description: SiiDescription,
    memory: Box<[u8]>,
    sii: SiiInterface,
    al: AlStateMachine,
    od: ObjectDictionary,
    /// Process data layout of SM2 (outputs) and SM3 (inputs), fixed on entering SAFE-OP.
    outputs: Vec<MappedEntry>,
    inputs: Vec<MappedEntry>,
    min_sync0_cycle_ns: u32,
    clock_origin_ns: u64,
    frame: FrameTimes,
    last_mailbox: Option<Outcome>,
    /// SYNC0 pulses handed out by [`SubDevice::take_sync0_pulses`] and the configuration
    /// they were counted under.
    sync0_taken: Option<(Sync0, u64)>,
    /// Local time of the last process-data write into the outputs in OP, ns (the sync
    /// manager watchdog's trigger); `None` until the first one after entering OP.
    outputs_written_ns: Option<u64>,
}

impl SubDevice {
    /// A SubDevice after power-up: INIT, registers reset, EEPROM loaded.
    pub fn new(config: SubDeviceConfig) -> Result<Self, SiiError> {
        let image = config.sii.build()?;
        let mut device = Self {
            esc: config.esc,
            description: config.sii,
            memory: vec![0u8; MEMORY_LEN].into_boxed_slice(),
            sii: SiiInterface::new(image),
            al: AlStateMachine::new(),
            od: config.dictionary,
            outputs: Vec::new(),
            inputs: Vec::new(),
            min_sync0_cycle_ns: config.min_sync0_cycle_ns,
            clock_origin_ns: config.clock_origin_ns,
            frame: FrameTimes::default(),
            last_mailbox: None,
            sync0_taken: None,
            outputs_written_ns: None,
        };
        device.esc.write_to(&mut device.memory);
        device.sii.reset(&mut device.memory);
        let _ = le::put_u16(
            &mut device.memory,
            usize::from(registers::STATION_ALIAS),
            device.description.alias,
        );
        let _ = le::put_u16(
            &mut device.memory,
            usize::from(registers::WATCHDOG_DIVIDER),
            registers::WATCHDOG_DIVIDER_DEFAULT,
        );
        let _ = le::put_u16(
            &mut device.memory,
            usize::from(registers::SM_WATCHDOG_TIME),
            registers::SM_WATCHDOG_TIME_DEFAULT,
        );
        device.set_port1_linked(false);
        device.store_al_status();
        Ok(device)
    }

    pub fn identity(&self) -> Identity {
        self.description.identity
    }

    /// The name (order code) in the SII.
    pub fn name(&self) -> &str {
        &self.description.name
    }

    /// The configured station address (0x0010).
    pub fn station_address(&self) -> u16 {
        le::u16_at(&self.memory, usize::from(registers::STATION_ADDRESS)).unwrap_or(0)
    }

    pub fn al_state(&self) -> AlState {
        self.al.state()
    }

    /// The refusal or local error pending acknowledgement, if any.
    pub fn al_error(&self) -> Option<AlStatusCode> {
        self.al.error()
    }

    /// A local AL error (the application behind the ESC lost SYNC0, ...): SAFE-OP with the
    /// error flag and `code` in AL status, outputs no longer taken.
    pub fn raise_al_error(&mut self, code: AlStatusCode) {
        self.al.fault(code);
        self.outputs_written_ns = None;
        self.store_al_status();
    }

    /// Sets the sync manager watchdog time (0x0420) in watchdog units (100 us with the
    /// power-up divider; 0 switches it off), as a SubDevice's EEPROM or PDI configures it.
    pub fn set_sm_watchdog_time(&mut self, units: u16) {
        let _ = le::put_u16(
            &mut self.memory,
            usize::from(registers::SM_WATCHDOG_TIME),
            units,
        );
    }

    /// The sync manager watchdog time from registers 0x0400 and 0x0420, ns; `None` when
    /// switched off (0x0420 = 0).
    pub fn sm_watchdog_ns(&self) -> Option<u64> {
        let divider = le::u16_at(&self.memory, usize::from(registers::WATCHDOG_DIVIDER))?;
        let time = le::u16_at(&self.memory, usize::from(registers::SM_WATCHDOG_TIME))?;
        (time > 0).then(|| (u64::from(divider) + 2) * 40 * u64::from(time))
    }

    /// The sync manager watchdog, run by the segment before a frame reaches the SubDevice
    /// at segment time `arrival_ns` (and before the application latches its inputs): in OP,
    /// more than the watchdog time since the last output write and the ESC is in SAFE-OP
    /// with AL status code 0x001B.
    pub fn check_watchdog(&mut self, arrival_ns: u64) {
        let (Some(last), Some(limit)) = (self.outputs_written_ns, self.sm_watchdog_ns()) else {
            return;
        };
        let local = self.clock_origin_ns.wrapping_add(arrival_ns);
        if self.al.state() == AlState::Op && local.saturating_sub(last) > limit {
            self.raise_al_error(AlStatusCode::SyncManagerWatchdog);
        }
    }

    pub fn dictionary(&self) -> &ObjectDictionary {
        &self.od
    }

    /// The dictionary, for the application behind the ESC (a drive writes its status word and
    /// actual values here; they reach the inputs on the next frame).
    pub fn dictionary_mut(&mut self) -> &mut ObjectDictionary {
        &mut self.od
    }

    /// ESC memory (registers and process RAM).
    pub fn memory(&self) -> &[u8] {
        &self.memory
    }

    /// The EEPROM contents.
    pub fn eeprom(&self) -> &[u8] {
        self.sii.image()
    }

    /// What the last mailbox request did.
    pub fn last_mailbox(&self) -> Option<Outcome> {
        self.last_mailbox
    }

    /// SYNC0 as the MainDevice configured it, if active.
    pub fn sync0(&self) -> Option<Sync0> {
        Sync0::configured(&self.memory)
    }

    /// The SYNC0 pulses generated since the last call, up to segment time `segment_ns`
    /// (inclusive): the SYNC0 unit as the application behind the ESC sees it. Pulses
    /// before SYNC0 was first seen active, or under an earlier configuration, are not
    /// counted; none while SYNC0 is off.
    pub fn take_sync0_pulses(&mut self, segment_ns: u64) -> u64 {
        let Some(sync0) = self.sync0() else {
            self.sync0_taken = None;
            return 0;
        };
        let until = sync0.pulses_until(self.system_time_at(segment_ns));
        let taken = match self.sync0_taken {
            Some((seen, taken)) if seen == sync0 => taken,
            _ => until,
        };
        self.sync0_taken = Some((sync0, until.max(taken)));
        until.saturating_sub(taken)
    }

    /// Segment time of the next SYNC0 pulse after segment time `segment_ns`, ns (`None`
    /// while SYNC0 is off).
    pub fn next_sync0_ns(&self, segment_ns: u64) -> Option<u64> {
        let sync0 = self.sync0()?;
        let now = self.system_time_at(segment_ns);
        Some(segment_ns + (sync0.next_after(now) - now))
    }

    /// System time at segment time `segment_ns` (ns).
    pub fn system_time_at(&self, segment_ns: u64) -> u64 {
        dc::system_time(&self.memory, self.clock_origin_ns.wrapping_add(segment_ns))
    }

    /// Sets the link state of port 1 (another SubDevice behind this one) in DL status.
    pub fn set_port1_linked(&mut self, linked: bool) {
        let _ = le::put_u16(
            &mut self.memory,
            usize::from(registers::DL_STATUS),
            registers::dl_status(linked),
        );
    }

    /// A frame reaches port 0 at segment time `arrival_ns` and, when port 1 is linked,
    /// comes back through port 1 at `return_ns`: refreshes system time and the inputs.
    pub fn begin_frame(&mut self, arrival_ns: u64, return_ns: Option<u64>) {
        self.frame = FrameTimes {
            local: self.clock_origin_ns.wrapping_add(arrival_ns),
            port1: return_ns.map(|t| self.clock_origin_ns.wrapping_add(t)),
        };
        dc::refresh(&mut self.memory, self.frame.local);
        if self.al.state() >= AlState::SafeOp {
            let base = usize::from(self.description.inputs_start);
            for e in &self.inputs {
                if let (Some(value), Some(dst)) = (
                    self.od.get(e.index, e.sub),
                    self.memory
                        .get_mut(base + e.offset..base + e.offset + e.len),
                ) {
                    if value.len() == dst.len() {
                        dst.copy_from_slice(value);
                    }
                }
            }
        }
    }

    /// The frame has passed: in OP, the outputs reach the dictionary.
    pub fn end_frame(&mut self) {
        if self.al.state() != AlState::Op {
            return;
        }
        let base = usize::from(self.description.outputs_start);
        for e in &self.outputs {
            if let Some(src) = self.memory.get(base + e.offset..base + e.offset + e.len) {
                let _ = self.od.set(e.index, e.sub, src);
            }
        }
    }

    /// Handles one PDU as it passes: addressing, memory access with its side effects, and
    /// the working counter.
    pub fn process_pdu(&mut self, pdu: &mut Pdu<'_>) {
        let access = pdu.command.access();
        let increment = match pdu.command.addressing() {
            Addressing::None => 0,
            Addressing::Position => {
                let position = pdu.station();
                pdu.set_station(position.wrapping_add(1));
                let addressed = position == 0;
                self.addressed_access(access, addressed, pdu.offset(), pdu.data)
            }
            Addressing::Configured => {
                let addressed = pdu.station() == self.station_address();
                self.addressed_access(access, addressed, pdu.offset(), pdu.data)
            }
            Addressing::Broadcast => {
                pdu.set_station(pdu.station().wrapping_add(1));
                self.physical(access, pdu.offset(), pdu.data, true)
            }
            Addressing::Logical => self.logical(access, pdu.address, pdu.data),
        };
        pdu.working_counter = pdu.working_counter.wrapping_add(increment);
    }

    /// Access of a position or station addressed PDU: the addressed SubDevice reads or
    /// writes; of ARMW/FRMW it reads and all others write.
    fn addressed_access(
        &mut self,
        access: Access,
        addressed: bool,
        offset: u16,
        data: &mut [u8],
    ) -> u16 {
        match (access, addressed) {
            (Access::ReadMultipleWrite, true) => self.physical(Access::Read, offset, data, false),
            (Access::ReadMultipleWrite, false) => self.physical(Access::Write, offset, data, false),
            (_, true) => self.physical(access, offset, data, false),
            (_, false) => 0,
        }
    }

    /// Reads and/or writes ESC memory at `[offset, offset + len)`; the working counter
    /// increment (read 1, write 1, read-write 1 + 2). Broadcast reads OR into the data.
    fn physical(&mut self, access: Access, offset: u16, data: &mut [u8], broadcast: bool) -> u16 {
        let start = u32::from(offset);
        let end = start + data.len() as u32;
        let (read, write) = match access {
            Access::Read => (self.may_read(start, end), false),
            Access::Write => (false, self.may_write(start, end)),
            Access::ReadWrite => (self.may_read(start, end), self.may_write(start, end)),
            Access::None | Access::ReadMultipleWrite => (false, false),
        };
        for (i, byte) in data.iter_mut().enumerate() {
            let address = start as usize + i;
            let old = self.memory.get(address).copied().unwrap_or(0);
            if write && address <= usize::from(u16::MAX) && registers::writable(address as u16) {
                if let Some(slot) = self.memory.get_mut(address) {
                    *slot = *byte;
                }
            }
            if read {
                *byte = if broadcast { *byte | old } else { old };
            }
        }
        if write {
            self.after_write(start, end);
        }
        if read {
            self.after_read(start, end);
        }
        match access {
            Access::ReadWrite => u16::from(read) + 2 * u16::from(write),
            _ => u16::from(read || write),
        }
    }

    /// LRD/LWR/LRW through the FMMUs: writes first (with the frame's data), then reads.
    /// Working counter: read 1, write 1, LRW read 1 + write 2.
    fn logical(&mut self, access: Access, address: u32, data: &mut [u8]) -> u16 {
        let (do_read, do_write) = match access {
            Access::Read => (true, false),
            Access::Write => (false, true),
            Access::ReadWrite => (true, true),
            Access::None | Access::ReadMultipleWrite => (false, false),
        };
        let (mut read, mut written) = (false, false);
        for pass_write in [true, false] {
            if (pass_write && !do_write) || (!pass_write && !do_read) {
                continue;
            }
            for n in 0..u16::from(self.esc.fmmus.min(16)) {
                let Some(fmmu) = Fmmu::read_from(&self.memory, n) else {
                    continue;
                };
                if (pass_write && !fmmu.write) || (!pass_write && !fmmu.read) {
                    continue;
                }
                let Some((at, physical, len)) = fmmu.overlap(address, data.len()) else {
                    continue;
                };
                let part = &mut data[at..at + len];
                let access = if pass_write {
                    Access::Write
                } else {
                    Access::Read
                };
                if self.physical(access, physical, part, false) > 0 {
                    if pass_write {
                        written = true;
                    } else {
                        read = true;
                    }
                }
            }
        }
        if written && self.al.state() == AlState::Op {
            self.outputs_written_ns = Some(self.frame.local);
        }
        match access {
            Access::ReadWrite => u16::from(read) + 2 * u16::from(written),
            _ => u16::from(read || written),
        }
    }

    fn sync_managers(&self) -> impl Iterator<Item = (u16, SyncManager)> + '_ {
        (0..u16::from(self.esc.sync_managers.min(16)))
            .filter_map(|n| SyncManager::read_from(&self.memory, n).map(|sm| (n, sm)))
    }

    fn mailbox_full(&self, n: u16) -> bool {
        self.memory
            .get(SyncManager::status_address(n))
            .is_some_and(|s| s & STATUS_MAILBOX_FULL != 0)
    }

    fn set_mailbox_full(&mut self, n: u16, full: bool) {
        if let Some(s) = self.memory.get_mut(SyncManager::status_address(n)) {
            if full {
                *s |= STATUS_MAILBOX_FULL;
            } else {
                *s &= !STATUS_MAILBOX_FULL;
            }
        }
    }

    /// Process data sync managers are open only in SAFE-OP and OP.
    fn process_data_active(&self) -> bool {
        self.al.state() >= AlState::SafeOp
    }

    /// Whether the MainDevice may read `[start, end)`: the send mailbox only when full, the
    /// receive mailbox never, input buffers only with process data active.
    fn may_read(&self, start: u32, end: u32) -> bool {
        self.sync_managers()
            .filter(|(_, sm)| sm.overlaps(start, end))
            .all(|(n, sm)| match (sm.mode, sm.direction) {
                (SmMode::Mailbox, SmDirection::MainDeviceReads) => self.mailbox_full(n),
                (SmMode::Mailbox, SmDirection::MainDeviceWrites) => false,
                (SmMode::Buffered, SmDirection::MainDeviceReads) => self.process_data_active(),
                (SmMode::Buffered, SmDirection::MainDeviceWrites) => false,
            })
    }

    /// Whether the MainDevice may write `[start, end)`: the receive mailbox only when empty,
    /// output buffers only with process data active.
    fn may_write(&self, start: u32, end: u32) -> bool {
        self.sync_managers()
            .filter(|(_, sm)| sm.overlaps(start, end))
            .all(|(n, sm)| match (sm.mode, sm.direction) {
                (SmMode::Mailbox, SmDirection::MainDeviceWrites) => !self.mailbox_full(n),
                (SmMode::Mailbox, SmDirection::MainDeviceReads) => false,
                (SmMode::Buffered, SmDirection::MainDeviceWrites) => self.process_data_active(),
                (SmMode::Buffered, SmDirection::MainDeviceReads) => false,
            })
    }

    fn overlaps(start: u32, end: u32, register: u16, len: u16) -> bool {
        start < u32::from(register) + u32::from(len) && end > u32::from(register)
    }

    /// Side effects of a write of `[start, end)`.
    fn after_write(&mut self, start: u32, end: u32) {
        if Self::overlaps(start, end, registers::AL_CONTROL, 2) {
            self.al_control_written();
        }
        if Self::overlaps(start, end, registers::SII_CONFIG, 16) {
            self.sii
                .after_write(&mut self.memory, start as u16, end.min(0xFFFF) as u16);
        }
        if Self::overlaps(start, end, registers::SM0, 16 * registers::SM_LEN) {
            for n in 0..u16::from(self.esc.sync_managers.min(16)) {
                let base = registers::SM0 + n * registers::SM_LEN;
                let enabled = SyncManager::read_from(&self.memory, n).is_some_and(|sm| sm.enabled);
                if Self::overlaps(start, end, base, registers::SM_LEN) && !enabled {
                    self.set_mailbox_full(n, false);
                }
            }
        }
        if Self::overlaps(start, end, registers::DC_TIME_PORT0, 4) {
            dc::latch(
                &mut self.memory,
                PortTimes {
                    port0: self.frame.local,
                    port1: self.frame.port1,
                },
            );
        }
        if Self::overlaps(start, end, registers::DC_SYSTEM_TIME, 8) {
            dc::compare_system_time(&mut self.memory, self.frame.local);
        }
        let receive = self.sync_managers().find(|(_, sm)| {
            sm.mode == SmMode::Mailbox && sm.direction == SmDirection::MainDeviceWrites
        });
        if let Some((n, sm)) = receive {
            if sm.covers_last_byte(start, end) {
                self.set_mailbox_full(n, true);
                self.serve_mailbox();
            }
        }
    }

    /// Side effects of a read of `[start, end)`: reading the last byte of the send mailbox
    /// empties it (and lets a waiting request through).
    fn after_read(&mut self, start: u32, end: u32) {
        let send = self.sync_managers().find(|(_, sm)| {
            sm.mode == SmMode::Mailbox && sm.direction == SmDirection::MainDeviceReads
        });
        if let Some((n, sm)) = send {
            if sm.covers_last_byte(start, end) && self.mailbox_full(n) {
                self.set_mailbox_full(n, false);
                self.serve_mailbox();
            }
        }
    }

    /// Serves the receive mailbox into the send mailbox when a request waits and the send
    /// mailbox is free.
    fn serve_mailbox(&mut self) {
        let mut receive = None;
        let mut send = None;
        for (n, sm) in self.sync_managers() {
            if sm.mode == SmMode::Mailbox && sm.enabled {
                match sm.direction {
                    SmDirection::MainDeviceWrites => receive = receive.or(Some((n, sm))),
                    SmDirection::MainDeviceReads => send = send.or(Some((n, sm))),
                }
            }
        }
        let (Some((rn, rx)), Some((sn, tx))) = (receive, send) else {
            return;
        };
        if !self.mailbox_full(rn) || self.mailbox_full(sn) {
            return;
        }
        let rx_range = usize::from(rx.start)..usize::from(rx.start) + usize::from(rx.len);
        let tx_range = usize::from(tx.start)..usize::from(tx.start) + usize::from(tx.len);
        let state = self.al.state();
        let Some((request, response)) = disjoint(&mut self.memory, rx_range, tx_range) else {
            return;
        };
        let outcome = mailbox::serve(request, response, &mut self.od, state);
        self.last_mailbox = Some(outcome);
        self.set_mailbox_full(rn, false);
        if outcome.responds() {
            self.set_mailbox_full(sn, true);
        }
    }

    fn al_control_written(&mut self) {
        let control = le::u16_at(&self.memory, usize::from(registers::AL_CONTROL)).unwrap_or(0);
        let checks = self.transition_checks(control);
        if let Some(state) = self.al.request(control, &checks) {
            self.entered(state);
        }
        self.store_al_status();
    }

    /// The checks a requested transition needs (computed only for the one requested).
    fn transition_checks(&self, control: u16) -> TransitionChecks {
        let requested = AlState::from_code((control & 0x0F) as u8);
        let mut checks = TransitionChecks {
            mailbox_ok: true,
            outputs_ok: true,
            inputs_ok: true,
            dc: Ok(()),
        };
        match (self.al.state(), requested) {
            (AlState::Init, Some(AlState::PreOp)) => {
                checks.mailbox_ok = self.mailbox_configured();
            }
            (AlState::PreOp, Some(AlState::SafeOp)) => {
                checks.outputs_ok = self.process_data_configured(RX_ASSIGN);
                checks.inputs_ok = self.process_data_configured(TX_ASSIGN);
                checks.dc = match Sync0::configured(&self.memory) {
                    Some(s) if s.cycle < u64::from(self.min_sync0_cycle_ns) => {
                        Err(AlStatusCode::SyncCycleTimeTooSmall)
                    }
                    _ => Ok(()),
                };
            }
            _ => {}
        }
        checks
    }

    /// SM0 and SM1 match the SII's mailboxes.
    fn mailbox_configured(&self) -> bool {
        let matches = |n: u16, area: MailboxArea, direction: SmDirection| {
            SyncManager::read_from(&self.memory, n).is_some_and(|sm| {
                sm.enabled
                    && sm.mode == SmMode::Mailbox
                    && sm.direction == direction
                    && sm.start == area.start
                    && sm.len == area.len
            })
        };
        matches(
            0,
            self.description.receive_mailbox,
            SmDirection::MainDeviceWrites,
        ) && matches(
            1,
            self.description.send_mailbox,
            SmDirection::MainDeviceReads,
        )
    }

    /// SM2 (outputs) or SM3 (inputs) matches the assigned PDOs' length and the SII's start.
    fn process_data_configured(&self, assign: u16) -> bool {
        let (n, start, direction) = if assign == RX_ASSIGN {
            (
                2,
                self.description.outputs_start,
                SmDirection::MainDeviceWrites,
            )
        } else {
            (
                3,
                self.description.inputs_start,
                SmDirection::MainDeviceReads,
            )
        };
        let Some(layout) = self.od.layout(assign) else {
            return false;
        };
        let len: usize = layout.iter().map(|e| e.len).sum();
        let Some(sm) = SyncManager::read_from(&self.memory, n) else {
            return false;
        };
        if len == 0 {
            return !sm.enabled || sm.len == 0;
        }
        sm.enabled
            && sm.mode == SmMode::Buffered
            && sm.direction == direction
            && sm.start == start
            && usize::from(sm.len) == len
    }

    fn entered(&mut self, state: AlState) {
        match state {
            AlState::SafeOp => {
                self.outputs = self.od.layout(RX_ASSIGN).unwrap_or_default();
                self.inputs = self.od.layout(TX_ASSIGN).unwrap_or_default();
            }
            AlState::Init => {
                for n in 0..u16::from(self.esc.sync_managers.min(16)) {
                    self.set_mailbox_full(n, false);
                }
            }
            AlState::Op => self.outputs_written_ns = None,
            AlState::PreOp | AlState::Bootstrap => {}
        }
    }

    fn store_al_status(&mut self) {
        let status = self.al.status_register();
        let code = self.al.status_code_register();
        let _ = le::put_u16(&mut self.memory, usize::from(registers::AL_STATUS), status);
        let _ = le::put_u16(
            &mut self.memory,
            usize::from(registers::AL_STATUS_CODE),
            code,
        );
    }
}

/// Two disjoint ranges of one slice, mutably: (`a`, `b`); `None` when they overlap or do not
/// fit.
fn disjoint(
    memory: &mut [u8],
    a: core::ops::Range<usize>,
    b: core::ops::Range<usize>,
) -> Option<(&mut [u8], &mut [u8])> {
    if a.end > memory.len() || b.end > memory.len() || (a.start < b.end && b.start < a.end) {
        return None;
    }
    if a.start < b.start {
        let (low, high) = memory.split_at_mut(b.start);
        Some((&mut low[a], &mut high[..b.end - b.start]))
    } else {
        let (low, high) = memory.split_at_mut(a.start);
        Some((&mut high[..a.end - a.start], &mut low[b]))
    }
}

//! The ESC register map a MainDevice touches (ETG.1000.4 / the Beckhoff ESC datasheets), and
//! the read-only identification registers of an emulated ESC.

/// ESC type (u8).
pub const TYPE: u16 = 0x0000;
/// ESC revision (u8).
pub const REVISION: u16 = 0x0001;
/// ESC build (u16).
pub const BUILD: u16 = 0x0002;
/// Number of FMMUs (u8).
pub const FMMU_COUNT: u16 = 0x0004;
/// Number of sync managers (u8).
pub const SM_COUNT: u16 = 0x0005;
/// Process RAM size, KiB (u8).
pub const RAM_SIZE: u16 = 0x0006;
/// Port descriptor, 2 bits per port (u8).
pub const PORT_DESCRIPTOR: u16 = 0x0007;
/// ESC features supported (u16).
pub const FEATURES: u16 = 0x0008;
/// Configured station address (u16).
pub const STATION_ADDRESS: u16 = 0x0010;
/// Configured station alias (u16).
pub const STATION_ALIAS: u16 = 0x0012;
/// DL status (u16): PDI and link state of the ports.
pub const DL_STATUS: u16 = 0x0110;
/// AL control (u16), written by the MainDevice to request a state.
pub const AL_CONTROL: u16 = 0x0120;
/// AL status (u16): the current state and the error flag.
pub const AL_STATUS: u16 = 0x0130;
/// AL status code (u16): why the last state change was refused.
pub const AL_STATUS_CODE: u16 = 0x0134;
/// EEPROM configuration (u8) and PDI access state (u8).
pub const SII_CONFIG: u16 = 0x0500;
/// EEPROM control/status (u16).
pub const SII_CONTROL: u16 = 0x0502;
/// EEPROM word address (u32).
pub const SII_ADDRESS: u16 = 0x0504;
/// EEPROM data (8 bytes read, 2 bytes written).
pub const SII_DATA: u16 = 0x0508;
/// First FMMU; FMMU `n` is at `FMMU0 + 16 n`.
pub const FMMU0: u16 = 0x0600;
/// Bytes per FMMU.
pub const FMMU_LEN: u16 = 16;
/// First sync manager; SM `n` is at `SM0 + 8 n`.
pub const SM0: u16 = 0x0800;
/// Bytes per sync manager.
pub const SM_LEN: u16 = 8;
/// Receive time of port 0 (u32, ns); a write latches the receive times of all ports.
pub const DC_TIME_PORT0: u16 = 0x0900;
/// System time (u64, ns); a write (FRMW/BWR of the reference's time) feeds the drift control.
pub const DC_SYSTEM_TIME: u16 = 0x0910;
/// Local time when the latching frame reached the processing unit (u64, ns).
pub const DC_RECEIVE_TIME_PU: u16 = 0x0918;
/// System time offset (u64, ns): system time = local time + offset.
pub const DC_SYSTEM_TIME_OFFSET: u16 = 0x0920;
/// System time transmission delay from the reference clock (u32, ns).
pub const DC_SYSTEM_TIME_DELAY: u16 = 0x0928;
/// System time difference (u32: bit 31 the sign, bits 30..0 the magnitude in ns).
pub const DC_SYSTEM_TIME_DIFFERENCE: u16 = 0x092C;
/// Watchdog divider (u16): the watchdog's time unit is (divider + 2) x 40 ns.
pub const WATCHDOG_DIVIDER: u16 = 0x0400;
/// Sync manager (process data) watchdog time (u16), in watchdog units; 0 switches it off.
pub const SM_WATCHDOG_TIME: u16 = 0x0420;
/// An ESC's power-up watchdog divider: 2498, a unit of 100 us.
pub const WATCHDOG_DIVIDER_DEFAULT: u16 = 2498;
/// An ESC's power-up sync manager watchdog time: 1000 units, 100 ms.
pub const SM_WATCHDOG_TIME_DEFAULT: u16 = 1000;
/// Cyclic unit control (u8).
pub const DC_CYCLIC_UNIT_CONTROL: u16 = 0x0980;
/// Sync activation (u8): bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1.
pub const DC_SYNC_ACTIVE: u16 = 0x0981;
/// Start time of cyclic operation, system time (u64, ns).
pub const DC_SYNC_START_TIME: u16 = 0x0990;
/// SYNC0 cycle time (u32, ns).
pub const DC_SYNC0_CYCLE: u16 = 0x09A0;
/// SYNC1 cycle time (u32, ns).
pub const DC_SYNC1_CYCLE: u16 = 0x09A4;
/// First byte of process RAM.
pub const PROCESS_RAM: u16 = 0x1000;

/// Whether an EtherCAT write may change the byte at `address`. Identification, DL and AL
/// status, the SII status and the DC latches are read only; the SM status bytes are the
/// ESC's own.
pub fn writable(address: u16) -> bool {
    match address {
        0x0000..=0x000F => false,
        0x0110..=0x0111 => false,
        0x0130..=0x0137 => false,
        0x0900..=0x090F | 0x0918..=0x091F | 0x092C..=0x092F => false,
        a if (SM0..SM0 + 16 * SM_LEN).contains(&a) => (a - SM0) % SM_LEN != 5,
        _ => true,
    }
}

/// ESC identification: the read-only registers 0x0000..0x000A.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EscInfo {
    /// ESC type (0x11 ET1100, 0xC8 LAN9252, ...).
    pub esc_type: u8,
    pub revision: u8,
    pub build: u16,
    /// FMMUs the ESC has (at most 16).
    pub fmmus: u8,
    /// Sync managers the ESC has (at most 16).
    pub sync_managers: u8,
    /// Process RAM, KiB.
    pub ram_kib: u8,
    /// Feature bits of register 0x0008 (DC supported, 64-bit DC, enhanced DC sync, ...).
    pub features: u16,
}

impl EscInfo {
    /// DC supported (bit 2), 64-bit system time (bit 3), enhanced DC SYNC activation (bit 8).
    pub const FEATURES_DC64: u16 = (1 << 2) | (1 << 3) | (1 << 8);

    /// An ET1100-like ESC: 8 FMMUs, 8 sync managers, 8 KiB of process RAM, 64-bit DC.
    pub const fn et1100_like() -> Self {
        Self {
            esc_type: 0x11,
            revision: 0x00,
            build: 0x0003,
            fmmus: 8,
            sync_managers: 8,
            ram_kib: 8,
            features: Self::FEATURES_DC64,
        }
    }

    /// Writes the identification registers into ESC memory.
    pub fn write_to(&self, memory: &mut [u8]) {
        let regs = [
            self.esc_type,
            self.revision,
            self.build.to_le_bytes()[0],
            self.build.to_le_bytes()[1],
            self.fmmus,
            self.sync_managers,
            self.ram_kib,
            // Ports 0 and 1 MII (0b11), ports 2 and 3 not implemented.
            0x0F,
            self.features.to_le_bytes()[0],
            self.features.to_le_bytes()[1],
        ];
        if let Some(dst) = memory.get_mut(..regs.len()) {
            dst.copy_from_slice(&regs);
        }
    }
}

/// DL status (0x0110) of a SubDevice whose port 0 is linked (towards the MainDevice) and whose
/// port 1 is linked when another SubDevice follows: PDI operational, watchdog ok, link and
/// communication bits per port; a closed port loops back.
pub fn dl_status(port1_linked: bool) -> u16 {
    let mut status: u16 = 0b11; // PDI operational, PDI watchdog reloaded
    status |= 1 << 4; // link port 0
    status |= 1 << 9; // communication on port 0 (loop open)
    if port1_linked {
        status |= 1 << 5;
        status |= 1 << 11;
    } else {
        status |= 1 << 10; // loop port 1 closed
    }
    status |= 1 << 12 | 1 << 14; // ports 2 and 3 closed
    status
}

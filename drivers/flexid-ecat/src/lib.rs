//! EtherCAT for flexid (issue 18): a sans-I/O emulation of EtherCAT SubDevices with a
//! simulated CiA 402 servo behind them, its in-process link to ethercrab's MainDevice, and the
//! EtherCAT transport of the sweep.
//!
//! * [`frame`]: EtherCAT frames (Ethernet header 0x88A4, EtherCAT header, the PDU chain) and
//!   the commands with their addressing and working-counter semantics.
//! * [`esc`]: one emulated SubDevice: ESC memory and registers ([`esc::registers`]), the SII
//!   EEPROM and its interface ([`esc::sii`]), the AL state machine with status codes
//!   ([`esc::al`]), sync managers and FMMUs, the CoE SDO server ([`esc::mailbox`]) over an
//!   object dictionary with the PDO mapping rules ([`esc::dictionary`]), distributed clocks
//!   and SYNC0 ([`esc::dc`]).
//! * [`Segment`]: SubDevices in ring order processing a frame in place, as a line of ESCs,
//!   and the [`Application`] behind each one, run around every process-data frame.
//! * [`servo`]: the simulated CiA 402 servo (cyclic synchronous torque) in front of the
//!   core's plant physics, the same drive as flexid-vdrive's on CAN.
//! * [`drive`]: [`EcatDrive`], a CiA 402 axis in CST on an ethercrab group in OP, the
//!   fieldbus-independent `flexid_canopen::CyclicDrive` the sweep loop runs over.
//! * [`profile`]: the firmware profile chosen from the SubDevice's SII identity.
//! * [`emulated`]: a line of emulated servos in front of a plant file.
//! * [`session`]: one MainDevice session (storage, link thread, discovery, bring-up, the
//!   drive handed to the caller, the link stopped), over the emulated line or an interface.
//! * [`inprocess`]: drives a [`Segment`] from ethercrab's `PduTx`/`PduRx` (no socket, no
//!   root): the always-run test tier.
//! * [`socket_link`] (Linux): serves a [`Segment`] on a network interface through an
//!   `AF_PACKET` raw socket (the veth tier; `flexid-vdrive --ethercat IFACE`), and
//!   [`sync0_clock`]: the segment's wall clock and the thread that runs SYNC0 pulses at
//!   their time (the servo's SYNC0 clock).
//!
//! Not emulated yet: segmented SDO transfers, complete access, SDO information, emergencies,
//! the 3-buffer exchange (one buffer), bit-granular FMMUs, the DC drift control loop (clocks
//! are exact), watchdogs, EoE/FoE/SoE, ports 2 and 3 (line topology only), alias addressing.
//!
//! ethercrab's SDO download is expedited only (at most 4 bytes): PDO mappings are written
//! entry by entry (sub-index 0 to 0, the entries, sub-index 0 to the count), which the
//! emulated dictionary enforces as CiA 301 does.

pub mod drive;
pub mod emulated;
pub mod esc;
pub mod frame;
pub mod inprocess;
mod le;
pub mod profile;
pub mod segment;
pub mod servo;
pub mod session;
#[cfg(target_os = "linux")]
pub mod socket_link;
pub mod sync0_clock;

pub use drive::{EcatConfig, EcatDrive, EcatError};
pub use esc::{SubDevice, SubDeviceConfig};
pub use profile::ProfileChoice;
pub use segment::{Application, CycleStats, FrameReport, Segment};
pub use servo::{Servo, ServoClock, ServoConfig};
pub use session::{with_drive, Link, SessionDrive, SessionError};

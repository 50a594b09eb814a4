//! The EtherCAT transport of the sweep: [`EcatDrive`], a CiA 402 axis in cyclic synchronous
//! torque mode on an ethercrab group in OP, implementing the fieldbus-independent
//! [`CyclicDrive`] of `flexid-canopen` (the sweep loop, supervisor and recordings stay as
//! they are).
//!
//! Lifecycle: [`EcatDrive::bring_up`] takes the group as ethercrab's init leaves it
//! (PRE-OP) and returns only an enabled drive:
//!
//! 1. CoE configuration of every SubDevice of the group: the CST mapping written entry by
//!    entry (ethercrab's SDO download is expedited, at most 4 bytes): 0x1C12:0 and 0x1C13:0
//!    to 0, RxPDO 0x1600 = controlword 0x6040, target torque 0x6071; TxPDO 0x1A00 =
//!    statusword 0x6041, position actual 0x6064, velocity actual 0x606C, torque actual
//!    0x6077 (each: sub 0 to 0, the entries, sub 0 to the count), then the assignments
//!    0x1C12:1 = 0x1600, 0x1C13:1 = 0x1A00 and their counts; modes of operation 0x6060 = 10;
//!    the driven axis's rated torque 0x6076 and encoder resolution 0x608F read back;
//! 2. SYNC0 at the cycle period (distributed clocks), PRE-OP -> SAFE-OP -> OP;
//! 3. the CiA 402 walk to Operation enabled through process data
//!    (`flexid_canopen::cia402::next_controlword` every exchange, target torque 0).
//!
//! [`CyclicDrive::cycle`]: the controlword and the target torque (per mille of 0x6076) into
//! the outputs, one `tx_rx` (the LRW and the AL status reads in one frame), then the
//! working counter, the AL states and the statusword checked and the inputs converted.
//! Pairing: the inputs of exchange `k` were latched by the drive just before the frame
//! passed, the outputs act just after it (the emulated servo, [`crate::servo`], does
//! exactly this in lock-step): the feedback of cycle `k` is the state before torque `k`
//! acts, as on CAN. No allocation in the cycle (the frame is ethercrab's preallocated
//! storage; `futures_lite::future::block_on` reuses its thread's parker).
//!
//! The exchange is ethercrab's `tx_rx_dc`: the frame also carries the DC reference's
//! system time (FRMW, the drift compensation of the others). From the exchange with the
//! shortest round trip the drive locates the SYNC0 pulses on the host's clock and offers
//! [`CyclicDrive::cycle_grid`]: a real-time sweep then starts its cycles
//! [`EcatConfig::send_after_sync0`] after a pulse, so each frame arrives between the pulse
//! that latched its inputs and the one that applies its outputs (a servo on its SYNC0
//! clock, [`crate::servo::ServoClock::Sync0`]: one cycle of I/O delay).
//!
//! The link (ethercrab's `tx_rx_task`, or [`crate::inprocess::SegmentLink`]) runs on another
//! thread.

use crate::profile::{choose, ProfileChoice, ProfileError};
use crate::servo::{object, MODE_CST};
use ethercrab::subdevice_group::{DcConfiguration, HasDc, Op, PreOp};
use ethercrab::{DcSync, DefaultLock, MainDevice, SubDeviceGroup, SubDeviceState};
use flexid_canopen::cia402::{next_controlword, Controlword, State, Statusword, Target};
use flexid_canopen::scaling::PositionUnwrap;
use flexid_canopen::{
    Counters, CyclicDrive, DriveErrorKind, Feedback, Identity, Profile, ProfileSet, Scaling,
};
use futures_lite::future::block_on;
use std::time::{Duration, Instant};
use thiserror::Error;

/// RxPDO 0x1600 entries (index << 16 | sub << 8 | bits): controlword, target torque.
pub const RX_PDO: [u32; 2] = [0x6040_0010, 0x6071_0010];
/// TxPDO 0x1A00 entries: statusword, position actual, velocity actual, torque actual.
pub const TX_PDO: [u32; 4] = [0x6041_0010, 0x6064_0020, 0x606C_0020, 0x6077_0010];
/// Output bytes of one axis: controlword (0..2), target torque (2..4).
pub const OUTPUT_BYTES: usize = 4;
/// Input bytes of one axis: statusword (0..2), position (2..6), velocity (6..10), torque
/// (10..12).
pub const INPUT_BYTES: usize = 12;
/// Working counter of one SubDevice in an LRW: inputs read (1) + outputs written (2).
pub const WKC_PER_SUBDEVICE: u16 = 3;

/// How to bring the axis up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EcatConfig {
    /// Position of the driven axis in the group (the others are configured the same and
    /// held with controlword 0, torque 0).
    pub axis: usize,
    /// Cycle period: SYNC0 period and the sweep's cycle.
    pub cycle: Duration,
    /// Delay from the DC configuration to the first SYNC0.
    pub sync0_start_delay: Duration,
    /// Most process-data exchanges the walk to Operation enabled may take.
    pub enable_exchanges: u32,
    /// Where in the SYNC0 cycle a real-time master's cycle starts: this long after a
    /// pulse ([`CyclicDrive::cycle_grid`]), so that its frame reaches the SubDevices after
    /// that pulse latched the inputs and before the next one applies the outputs.
    pub send_after_sync0: Duration,
    /// Consecutive cycles whose exchange may end after their deadline before the sweep is
    /// stopped with [`EcatError::MissedCycles`]: the least count; the limit applied is
    /// [`EcatConfig::missed_cycles_limit`] (this many and at least
    /// [`EcatConfig::max_missed_time`] worth of them).
    pub max_missed_cycles: u32,
    /// The shortest run of late exchanges that stops the sweep, as a time (default 50 ms,
    /// as the CANopen master's `max_missed_time`): a count alone is 1 ms at 4 kHz, shorter
    /// than one scheduling stall of a host without a real-time kernel, while a late
    /// exchange only holds the last torque for a cycle (the sweep records the held row).
    /// The drive's own process-data watchdog (the emulated servo's 100 cycles, an ESC's
    /// sync manager watchdog of typically 100 ms) is the safety limit beside it.
    pub max_missed_time: Duration,
    /// How the driven axis's firmware profile is chosen.
    pub profile: ProfileChoice,
}

impl EcatConfig {
    /// Axis 0 at `cycle_hz` (Hz), SYNC0 starting 1 ms after configuration, 20 exchanges to
    /// enable, a real-time cycle starting a fifth of a cycle after SYNC0, late exchanges in
    /// a row for at most 10 cycles and 50 ms, the profile chosen by identity.
    pub fn at_hz(cycle_hz: f64) -> Self {
        let cycle = Duration::from_secs_f64(1.0 / cycle_hz);
        Self {
            axis: 0,
            cycle,
            sync0_start_delay: Duration::from_millis(1),
            enable_exchanges: 20,
            send_after_sync0: cycle / 5,
            max_missed_cycles: 10,
            max_missed_time: Duration::from_millis(50),
            profile: ProfileChoice::ByIdentity,
        }
    }

    /// Consecutive late exchanges allowed: `max_missed_cycles`, or more when those are
    /// shorter than `max_missed_time` at the cycle (the CANopen master's rule).
    pub fn missed_cycles_limit(&self) -> u32 {
        let period_ns = self.cycle.as_nanos().max(1);
        let by_time = self.max_missed_time.as_nanos().div_ceil(period_ns);
        self.max_missed_cycles
            .max(by_time.min(u128::from(u32::MAX)) as u32)
    }
}

/// Why the EtherCAT transport failed; every variant names the cause and where.
#[derive(Debug, Error)]
pub enum EcatError {
    #[error("axis {axis} is not in the group of {len} SubDevices")]
    NoAxis { axis: usize, len: usize },
    #[error("SubDevice {position} ({address:#06x}): {stage}: {source}")]
    Configure {
        position: usize,
        address: u16,
        stage: &'static str,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error("group: {stage}: {source}")]
    Group {
        stage: &'static str,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error(
        "SubDevice {position}: process data {outputs} bytes out and {inputs} in; the CST \
         mapping gives {OUTPUT_BYTES} and {INPUT_BYTES}"
    )]
    ProcessImage {
        position: usize,
        outputs: usize,
        inputs: usize,
    },
    #[error("SubDevice {position} ({address:#06x}, {name}): {source}")]
    Profile {
        position: usize,
        address: u16,
        name: String,
        #[source]
        source: ProfileError,
    },
    #[error("SubDevice {position}: {what} {value} unusable")]
    Scaling {
        position: usize,
        what: &'static str,
        value: u32,
    },
    #[error("cycle {cycle}: process-data exchange failed: {source}")]
    Exchange {
        cycle: u64,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error(
        "cycle {cycle}: SubDevice lost: SubDevice {position} ({address:#06x}) did not answer \
         its AL status read; working counter {got}, expected {expected}"
    )]
    SubDeviceLost {
        cycle: u64,
        position: usize,
        address: u16,
        got: u16,
        expected: u16,
    },
    #[error(
        "cycle {cycle}: working counter {got}, expected {expected} ({subdevices} SubDevices \
         x {WKC_PER_SUBDEVICE})"
    )]
    WorkingCounter {
        cycle: u64,
        got: u16,
        expected: u16,
        subdevices: usize,
    },
    /// An AL error; the codes of [`SYNC_CODES`] read as "DC out of sync".
    #[error(
        "cycle {cycle}: {cause}: SubDevice {position} ({address:#06x}) left OP: {state}, AL \
         status code {code:#06x} ({text})",
        cause = al_cause(*code),
        text = ethercrab::AlStatusCode::from(*code)
    )]
    AlState {
        cycle: u64,
        position: usize,
        address: u16,
        state: SubDeviceState,
        code: u16,
    },
    #[error(
        "cycle {cycle}: missed cycles: {consecutive} exchanges in a row ended after their \
         deadline (budget {budget}, cycle {period_us} us)"
    )]
    MissedCycles {
        cycle: u64,
        consecutive: u32,
        budget: u32,
        period_us: u64,
    },
    #[error(
        "cycle {cycle}: drive fault: the axis is in {state:?}, not Operation enabled \
         (statusword {statusword:#06x}, error code 0x603F = {error_code:#06x})"
    )]
    Fault {
        cycle: u64,
        state: Option<State>,
        statusword: u16,
        error_code: u16,
    },
    #[error(
        "the walk to Operation enabled stopped in {state:?} (statusword {statusword:#06x}) \
         after {exchanges} exchanges"
    )]
    EnableTimeout {
        exchanges: u32,
        state: Option<State>,
        statusword: u16,
    },
}

/// AL status codes that mean the SubDevice lost the distributed clock's synchronisation:
/// synchronisation error, fatal SYNC error, no SYNC error, PLL error (ETG.1000.6).
pub const SYNC_CODES: [u16; 4] = [0x001A, 0x002C, 0x002D, 0x0032];

/// How an AL error reads: "DC out of sync" for the [`SYNC_CODES`], "AL error" otherwise.
pub fn al_cause(code: u16) -> &'static str {
    if SYNC_CODES.contains(&code) {
        "DC out of sync"
    } else {
        "AL error"
    }
}

/// The group in OP with SYNC0 configured.
pub type OpGroup<const S: usize, const P: usize> = SubDeviceGroup<S, P, DefaultLock, Op, HasDc>;

/// One decoded input image of the axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Inputs {
    statusword: u16,
    position: i32,
    velocity: i32,
    torque: i16,
}

impl Inputs {
    /// The axis's input bytes in the TxPDO layout ([`INPUT_BYTES`]; missing bytes read 0).
    fn decode(raw: &[u8]) -> Self {
        fn field<const N: usize>(raw: &[u8], at: usize) -> [u8; N] {
            raw.get(at..at + N)
                .and_then(|b| b.try_into().ok())
                .unwrap_or([0; N])
        }
        Self {
            statusword: u16::from_le_bytes(field(raw, 0)),
            position: i32::from_le_bytes(field(raw, 2)),
            velocity: i32::from_le_bytes(field(raw, 6)),
            torque: i16::from_le_bytes(field(raw, 10)),
        }
    }

    fn statusword_state(&self) -> Option<State> {
        Statusword(self.statusword).state()
    }
}

/// A CiA 402 axis in cyclic synchronous torque mode over EtherCAT, in Operation enabled.
pub struct EcatDrive<'md, const S: usize, const P: usize> {
    md: &'md MainDevice<'md>,
    group: OpGroup<S, P>,
    config: EcatConfig,
    scaling: Scaling,
    profile: Profile,
    /// The driven axis's SII identity (vendor id, product code, revision, serial).
    identity: Identity,
    unwrap: PositionUnwrap,
    previous_cw: Controlword,
    /// Exchanges since bring-up began (the walk included).
    exchanges: u64,
    /// Cycles since enable.
    cycle: u64,
    counters: Counters,
    expected_wkc: u16,
    last: Inputs,
    /// The SYNC0 grid on the host's clock: a pulse's instant, from the exchange with the
    /// shortest round trip so far (and those within [`SYNC0_RTT_SLACK`] of it).
    sync0: Option<Sync0Estimate>,
    /// The DC reference's system time as the last exchange's frame passed it, ns.
    last_dc_time_ns: u64,
    /// Consecutive cycles whose exchange ended after the deadline.
    missed_in_a_row: u32,
}

/// Round trips this much longer than the shortest seen still refresh the SYNC0 estimate
/// (so it follows a drifting clock).
pub const SYNC0_RTT_SLACK: Duration = Duration::from_micros(5);

/// A SYNC0 pulse located on the host's clock.
#[derive(Debug, Clone, Copy)]
struct Sync0Estimate {
    pulse: Instant,
    /// The round trip of the exchange it came from.
    rtt: Duration,
    /// The shortest round trip seen.
    best_rtt: Duration,
}

impl<'md, const S: usize, const P: usize> EcatDrive<'md, S, P> {
    /// Brings the axis up to Operation enabled in CST with the built-in firmware profiles;
    /// see the module documentation. Blocks; the link must run on another thread.
    pub fn bring_up(
        md: &'md MainDevice<'md>,
        group: SubDeviceGroup<S, P, DefaultLock, PreOp>,
        config: EcatConfig,
    ) -> Result<Self, EcatError> {
        Self::bring_up_with(md, group, config, &ProfileSet::builtin())
    }

    /// [`EcatDrive::bring_up`] choosing the driven axis's profile from `profiles`.
    pub fn bring_up_with(
        md: &'md MainDevice<'md>,
        group: SubDeviceGroup<S, P, DefaultLock, PreOp>,
        config: EcatConfig,
        profiles: &ProfileSet,
    ) -> Result<Self, EcatError> {
        block_on(Self::bring_up_async(md, group, config, profiles))
    }

    async fn bring_up_async(
        md: &'md MainDevice<'md>,
        mut group: SubDeviceGroup<S, P, DefaultLock, PreOp>,
        config: EcatConfig,
        profiles: &ProfileSet,
    ) -> Result<Self, EcatError> {
        let len = group.len();
        if config.axis >= len {
            return Err(EcatError::NoAxis {
                axis: config.axis,
                len,
            });
        }
        let mut scaling = None;
        let mut profile = None;
        let mut sii_identity = Identity::default();
        for position in 0..len {
            let sd = group
                .subdevice(md, position)
                .map_err(|source| EcatError::Group {
                    stage: "SubDevice",
                    source,
                })?;
            let address = sd.configured_address();
            let configure = |stage: &'static str| {
                move |source| EcatError::Configure {
                    position,
                    address,
                    stage,
                    source,
                }
            };
            if position == config.axis {
                let sii = sd.identity();
                let identity = Identity {
                    vendor_id: sii.vendor_id,
                    product_code: sii.product_id,
                    revision: sii.revision,
                    serial: sii.serial,
                    // 0x1000 is not read: the CST mapping below fails on anything but a
                    // CiA 402 drive
                    device_type: 0x0002_0192,
                };
                let chosen = choose(profiles, &identity, config.profile, config.cycle).map_err(
                    |source| EcatError::Profile {
                        position,
                        address,
                        name: sd.name().to_string(),
                        source,
                    },
                )?;
                profile = Some(chosen);
                sii_identity = identity;
            }
            for (assign, pdo, entries) in [
                (0x1C12u16, 0x1600u16, &RX_PDO[..]),
                (0x1C13, 0x1A00, &TX_PDO[..]),
            ] {
                sd.sdo_write(assign, 0, 0u8)
                    .await
                    .map_err(configure("clearing a PDO assignment"))?;
                sd.sdo_write(pdo, 0, 0u8)
                    .await
                    .map_err(configure("clearing a PDO mapping"))?;
                for (sub, &entry) in entries.iter().enumerate() {
                    sd.sdo_write(pdo, sub as u8 + 1, entry)
                        .await
                        .map_err(configure("writing a PDO mapping entry"))?;
                }
                sd.sdo_write(pdo, 0, entries.len() as u8)
                    .await
                    .map_err(configure("writing a PDO mapping count"))?;
                sd.sdo_write(assign, 1, pdo)
                    .await
                    .map_err(configure("assigning a PDO"))?;
                sd.sdo_write(assign, 0, 1u8)
                    .await
                    .map_err(configure("writing a PDO assignment count"))?;
            }
            sd.sdo_write(object::MODES, 0, MODE_CST)
                .await
                .map_err(configure("modes of operation 0x6060 = 10 (CST)"))?;
            if position == config.axis {
                let rated_mnm: u32 = sd
                    .sdo_read(object::RATED_TORQUE, 0)
                    .await
                    .map_err(configure("reading the rated torque 0x6076"))?;
                let increments: u32 = sd
                    .sdo_read(object::ENCODER_RESOLUTION, 1)
                    .await
                    .map_err(configure("reading the encoder increments 0x608F:1"))?;
                let revolutions: u32 = sd
                    .sdo_read(object::ENCODER_RESOLUTION, 2)
                    .await
                    .map_err(configure("reading the motor revolutions 0x608F:2"))?;
                for (what, value) in [
                    ("rated torque 0x6076 (mN m)", rated_mnm),
                    ("encoder increments 0x608F:1", increments),
                    ("motor revolutions 0x608F:2", revolutions),
                ] {
                    if value == 0 {
                        return Err(EcatError::Scaling {
                            position,
                            what,
                            value,
                        });
                    }
                }
                let increments_per_rev = f64::from(increments) / f64::from(revolutions);
                let rated_torque_nm = f64::from(rated_mnm) / 1000.0;
                scaling = profile
                    .as_ref()
                    .map(|p| p.scaling(increments_per_rev, rated_torque_nm));
            }
        }
        for mut sd in group.iter_mut(md) {
            sd.set_dc_sync(DcSync::Sync0);
        }
        let group = group
            .into_pre_op_pdi(md)
            .await
            .map_err(|source| EcatError::Group {
                stage: "PRE-OP with process data",
                source,
            })?
            .configure_dc_sync(
                md,
                DcConfiguration {
                    start_delay: config.sync0_start_delay,
                    sync0_period: config.cycle,
                    sync0_shift: Duration::ZERO,
                },
            )
            .await
            .map_err(|source| EcatError::Group {
                stage: "SYNC0 configuration",
                source,
            })?
            .into_safe_op(md)
            .await
            .map_err(|source| EcatError::Group {
                stage: "SAFE-OP",
                source,
            })?
            .into_op(md)
            .await
            .map_err(|source| EcatError::Group {
                stage: "OP",
                source,
            })?;
        for (position, sd) in group.iter(md).enumerate() {
            let (outputs, inputs) = (sd.outputs_raw().len(), sd.inputs_raw().len());
            if (outputs, inputs) != (OUTPUT_BYTES, INPUT_BYTES) {
                return Err(EcatError::ProcessImage {
                    position,
                    outputs,
                    inputs,
                });
            }
        }
        let (Some(scaling), Some(profile)) = (scaling, profile) else {
            return Err(EcatError::NoAxis {
                axis: config.axis,
                len,
            });
        };
        let mut drive = Self {
            md,
            expected_wkc: WKC_PER_SUBDEVICE * len as u16,
            group,
            config,
            scaling,
            profile,
            identity: sii_identity,
            unwrap: PositionUnwrap::default(),
            previous_cw: Controlword::default(),
            exchanges: 0,
            cycle: 0,
            counters: Counters::default(),
            last: Inputs::default(),
            sync0: None,
            last_dc_time_ns: 0,
            missed_in_a_row: 0,
        };
        drive.walk(Target::OperationEnabled).await?;
        drive.counters = Counters::default();
        drive.cycle = 0;
        Ok(drive)
    }

    /// Exchanges process data with `next_controlword` towards `target` (torque 0) until the
    /// statusword shows it.
    async fn walk(&mut self, target: Target) -> Result<(), EcatError> {
        for n in 0..self.config.enable_exchanges {
            // A pattern outside the standard's table (or no inputs yet): as Not ready to
            // switch on (Disable voltage).
            let seen = self
                .last
                .statusword_state()
                .unwrap_or(State::NotReadyToSwitchOn);
            let cw = next_controlword(seen, target);
            self.exchange(cw, 0).await?;
            let state = self.last.statusword_state();
            if state == Some(target.state()) {
                return Ok(());
            }
            if n + 1 == self.config.enable_exchanges {
                return Err(EcatError::EnableTimeout {
                    exchanges: n + 1,
                    state,
                    statusword: self.last.statusword,
                });
            }
        }
        Err(EcatError::EnableTimeout {
            exchanges: 0,
            state: self.last.statusword_state(),
            statusword: self.last.statusword,
        })
    }

    /// One process-data exchange: `cw` and `torque_permille` out, the axis's inputs in
    /// (`self.last`), the working counter and the AL states checked.
    async fn exchange(&mut self, cw: Controlword, torque_permille: i16) -> Result<(), EcatError> {
        let cycle = self.cycle;
        let cw = cw.after(self.previous_cw);
        self.previous_cw = cw;
        {
            let sd = self
                .group
                .subdevice(self.md, self.config.axis)
                .map_err(|source| EcatError::Exchange { cycle, source })?;
            let mut out = sd.outputs_raw_mut();
            out[0..2].copy_from_slice(&cw.0.to_le_bytes());
            out[2..4].copy_from_slice(&torque_permille.to_le_bytes());
        }
        let sent = Instant::now();
        let response = self
            .group
            .tx_rx_dc(self.md)
            .await
            .map_err(|source| EcatError::Exchange { cycle, source })?;
        self.last_dc_time_ns = response.extra.dc_system_time;
        self.locate_sync0(sent, Instant::now(), self.last_dc_time_ns);
        self.exchanges += 1;
        let got = response.working_counter;
        let expected = self.expected_wkc;
        let not_op = response
            .subdevice_states
            .iter()
            .enumerate()
            .find(|(_, s)| **s != SubDeviceState::Op);
        if got != expected {
            if let Some((position, _)) = response
                .subdevice_states
                .iter()
                .enumerate()
                .find(|(_, s)| **s == SubDeviceState::None)
            {
                let address = self
                    .group
                    .subdevice(self.md, position)
                    .map_or(0, |sd| sd.configured_address());
                return Err(EcatError::SubDeviceLost {
                    cycle,
                    position,
                    address,
                    got,
                    expected,
                });
            }
            if not_op.is_none() {
                return Err(EcatError::WorkingCounter {
                    cycle,
                    got,
                    expected,
                    subdevices: self.group.len(),
                });
            }
        }
        if let Some((position, &state)) = not_op {
            let sd = self
                .group
                .subdevice(self.md, position)
                .map_err(|source| EcatError::Exchange { cycle, source })?;
            let address = sd.configured_address();
            // The fault path: one more read for the code, allowed to take its time.
            let code =
                ethercrab::Command::fprd(address, ethercrab::RegisterAddress::AlStatusCode.into())
                    .receive::<u16>(self.md)
                    .await
                    .unwrap_or(0xFFFF);
            return Err(EcatError::AlState {
                cycle,
                position,
                address,
                state,
                code,
            });
        }
        let sd = self
            .group
            .subdevice(self.md, self.config.axis)
            .map_err(|source| EcatError::Exchange { cycle, source })?;
        self.last = Inputs::decode(&sd.inputs_raw());
        Ok(())
    }

    /// Locates the SYNC0 grid on the host's clock from one exchange: sent at `sent`,
    /// back at `back`, the DC reference's system time `dc_time_ns` (ns) as the frame
    /// passed it, taken at the middle of the round trip. SYNC0 pulses come at whole
    /// cycles of system time (ethercrab rounds the start time to them).
    fn locate_sync0(&mut self, sent: Instant, back: Instant, dc_time_ns: u64) {
        let rtt = back.saturating_duration_since(sent);
        let best_rtt = self.sync0.map_or(rtt, |e| e.best_rtt.min(rtt));
        if self
            .sync0
            .is_some_and(|e| rtt > e.best_rtt + SYNC0_RTT_SLACK)
        {
            return;
        }
        let period_ns = (self.config.cycle.as_nanos() as u64).max(1);
        let since_pulse = Duration::from_nanos(dc_time_ns % period_ns);
        let middle = sent + rtt / 2;
        let pulse = middle.checked_sub(since_pulse).unwrap_or(middle);
        self.sync0 = Some(Sync0Estimate {
            pulse,
            rtt,
            best_rtt,
        });
    }

    /// Where in the SYNC0 cycle the last exchange's frame passed the DC reference: its
    /// system time after the last pulse, ns (SYNC0 pulses at whole cycles of system time).
    pub fn last_sync0_phase_ns(&self) -> u64 {
        self.last_dc_time_ns % (self.config.cycle.as_nanos() as u64).max(1)
    }

    /// The SYNC0 pulse the last exchange's inputs were latched at: the pulses counted in
    /// the DC system time the frame read as it passed (SYNC0 at whole cycles of system
    /// time, no shift); `None` before SYNC0 is located.
    pub fn last_drive_cycle(&self) -> Option<u64> {
        self.sync0?;
        Some(self.last_dc_time_ns / (self.config.cycle.as_nanos() as u64).max(1))
    }

    /// The round trip of the exchange the SYNC0 grid was located from.
    pub fn sync0_round_trip(&self) -> Option<Duration> {
        self.sync0.map(|e| e.rtt)
    }

    /// Counts a cycle whose exchange ended after its deadline (`fresh` false); more than
    /// [`EcatConfig::missed_cycles_limit`] in a row is an error.
    fn count_missed(&mut self, cycle: u64, fresh: bool) -> Result<(), EcatError> {
        if fresh {
            self.missed_in_a_row = 0;
            return Ok(());
        }
        self.counters.missed += 1;
        self.counters.late += 1;
        self.missed_in_a_row += 1;
        let budget = self.config.missed_cycles_limit();
        if self.missed_in_a_row > budget {
            return Err(EcatError::MissedCycles {
                cycle,
                consecutive: self.missed_in_a_row,
                budget,
                period_us: self.config.cycle.as_micros() as u64,
            });
        }
        Ok(())
    }

    /// The driven axis's error code 0x603F, by SDO (the fault path: allowed to take its
    /// time); 0 when it cannot be read.
    async fn error_code(&self) -> u16 {
        match self.group.subdevice(self.md, self.config.axis) {
            Ok(sd) => sd.sdo_read::<u16>(object::ERROR_CODE, 0).await.unwrap_or(0),
            Err(_) => 0,
        }
    }

    /// The CiA 402 walk back to Switch on disabled (torque 0): the power stage off.
    pub fn disable(&mut self) -> Result<(), EcatError> {
        block_on(self.walk(Target::SwitchOnDisabled))
    }

    /// The group, e.g. for its SubDevices' identities.
    pub fn group(&self) -> &OpGroup<S, P> {
        &self.group
    }

    /// The driven axis's SII identity (vendor id, product code, revision, serial; the device
    /// type is not read, given as a CiA 402 servo's 0x00020192).
    pub fn identity(&self) -> Identity {
        self.identity
    }

    /// The driven axis's firmware profile.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// The unit conversions read at bring-up.
    pub fn scaling(&self) -> Scaling {
        self.scaling
    }

    /// Process-data exchanges since bring-up began, the walk included.
    pub fn exchanges(&self) -> u64 {
        self.exchanges
    }
}

impl<const S: usize, const P: usize> CyclicDrive for EcatDrive<'_, S, P> {
    type Error = EcatError;

    fn cycle(&mut self, torque_nm: f64, deadline: Instant) -> Result<Feedback, EcatError> {
        let sync_time = Instant::now();
        let setpoint = self.scaling.torque_permille(torque_nm);
        block_on(self.exchange(Controlword::ENABLE_OPERATION, setpoint.permille))?;
        let cycle = self.cycle;
        self.cycle += 1;
        self.counters.cycles += 1;
        if setpoint.saturated {
            self.counters.saturated += 1;
        }
        let fresh = Instant::now() <= deadline;
        self.count_missed(cycle, fresh)?;
        let state = self.last.statusword_state();
        if state != Some(State::OperationEnabled) {
            return Err(EcatError::Fault {
                cycle,
                state,
                statusword: self.last.statusword,
                error_code: block_on(self.error_code()),
            });
        }
        let position = self.unwrap.update(self.last.position);
        Ok(Feedback {
            cycle,
            sync_time,
            statusword: self.last.statusword,
            state,
            position_rad: self.scaling.position_rad(position),
            velocity_rad_s: self.scaling.velocity_rad_s(self.last.velocity),
            torque_nm: self.scaling.torque_nm(self.last.torque),
            torque_setpoint_nm: self.scaling.torque_nm(setpoint.permille),
            saturated: setpoint.saturated,
            fresh,
            drive_cycle: self.last_drive_cycle(),
            counters: self.counters,
        })
    }

    fn cycle_period(&self) -> Duration {
        self.config.cycle
    }

    fn rated_torque_nm(&self) -> f64 {
        self.scaling.rated_torque_nm
    }

    fn counters(&self) -> Counters {
        self.counters
    }

    /// A SYNC0 pulse located on the host's clock plus [`EcatConfig::send_after_sync0`].
    fn cycle_grid(&self) -> Option<Instant> {
        self.sync0.map(|e| e.pulse + self.config.send_after_sync0)
    }

    /// 1: a CiA 402 drive latching its process data at SYNC0 applies set-point `k` at the
    /// pulse after frame `k` and frame `k` reads the inputs of the pulse before it.
    fn grid_io_delay_cycles(&self) -> u32 {
        1
    }

    /// The causes by kind: the axis's CiA 402 fault, an AL error and DC out of sync are
    /// drive faults; a SubDevice lost and a wrong working counter are bus errors; missed
    /// cycles and exchanges timed out are lost feedback.
    fn error_kind(error: &EcatError) -> Option<DriveErrorKind> {
        Some(match error {
            EcatError::Fault { .. } | EcatError::AlState { .. } => DriveErrorKind::DriveFault,
            EcatError::SubDeviceLost { .. } | EcatError::WorkingCounter { .. } => {
                DriveErrorKind::Bus
            }
            EcatError::MissedCycles { .. }
            | EcatError::Exchange {
                source: ethercrab::error::Error::Timeout(_),
                ..
            } => DriveErrorKind::FeedbackLost,
            EcatError::Exchange { .. } => DriveErrorKind::Bus,
            _ => DriveErrorKind::Other,
        })
    }
}

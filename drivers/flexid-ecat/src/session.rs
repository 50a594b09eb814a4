//! One EtherCAT session: a MainDevice on its own PDU storage, its link on a thread of its
//! own, the group discovered and the drive brought up, handed to the caller, then the link
//! stopped and joined. Nothing outlives the call (no leaked storage), so a service can run
//! one session per sweep.
//!
//! The link is either the emulated line in process ([`Link::Emulated`], no socket, no
//! privilege) or a network interface through ethercrab's stock `tx_rx_task` (raw
//! `AF_PACKET` socket: root or `CAP_NET_RAW`, [`SessionError::Interface`] says so).

use crate::drive::{EcatConfig, EcatDrive, EcatError};
use crate::inprocess::{LinkError, SegmentLink, SharedSegment};
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use flexid_canopen::ProfileSet;
use futures_lite::future::block_on;
use std::time::Duration;
use thiserror::Error;

/// Frames in flight at most.
pub const MAX_FRAMES: usize = 16;
/// Largest PDU payload of a frame, bytes.
pub const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
/// Largest group: SubDevices.
pub const MAX_SUBDEVICES: usize = 16;
/// Largest process image of the group, bytes (16 axes x (4 out + 12 in) = 256).
pub const MAX_PDI: usize = 256;

/// The drive a session hands out.
pub type SessionDrive<'md> = EcatDrive<'md, MAX_SUBDEVICES, MAX_PDI>;

/// Where the frames go.
#[derive(Debug, Clone)]
pub enum Link {
    /// The emulated line, in process.
    Emulated(SharedSegment),
    /// A network interface (e.g. `eth1`), through ethercrab's `tx_rx_task`.
    Interface(String),
}

impl Link {
    /// For people: `emulated` or `interface eth1`.
    pub fn describe(&self) -> String {
        match self {
            Link::Emulated(_) => "emulated EtherCAT line (in process)".into(),
            Link::Interface(i) => format!("EtherCAT interface {i}"),
        }
    }
}

/// Why a session could not run the drive.
#[derive(Debug, Error)]
pub enum SessionError {
    #[error(
        "EtherCAT interface {interface}: {source} (a raw socket needs root or CAP_NET_RAW: \
         `setcap cap_net_raw+ep` on the binary, or AmbientCapabilities=CAP_NET_RAW in the \
         systemd unit)"
    )]
    Interface {
        interface: String,
        #[source]
        source: std::io::Error,
    },
    #[error("EtherCAT discovery on {link}: {source}")]
    Discovery {
        link: String,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error("bring-up: {0}")]
    BringUp(#[source] EcatError),
    #[error("the EtherCAT link stopped: {0}")]
    Link(String),
}

/// Runs `run` on the drive brought up on `link` with `config` and `profiles`, then stops
/// the link. Blocks the calling thread (the cycle thread) for the whole session.
pub fn with_drive<R>(
    link: Link,
    config: EcatConfig,
    profiles: &ProfileSet,
    run: impl for<'md> FnOnce(SessionDrive<'md>) -> R,
) -> Result<R, SessionError> {
    let storage = Box::new(PduStorage::<MAX_FRAMES, MAX_PDU_DATA>::new());
    let (tx, rx, pdu_loop) = storage
        .try_split()
        .map_err(|()| SessionError::Link("PDU storage already split".into()))?;
    let timeouts = Timeouts {
        state_transition: Duration::from_millis(2000),
        // The emulated link loses no frame, it can only be late (a loaded host deschedules
        // its thread): a long PDU timeout keeps a lock-step sweep going; a line keeps
        // ethercrab's default, so a lost frame ends the sweep quickly.
        pdu: match link {
            Link::Emulated(_) => Duration::from_secs(1),
            Link::Interface(_) => Timeouts::default().pdu,
        },
        ..Timeouts::default()
    };
    let md_config = MainDeviceConfig {
        dc_static_sync_iterations: 1000,
        ..MainDeviceConfig::default()
    };
    let md = MainDevice::new(pdu_loop, timeouts, md_config);
    let describe = link.describe();
    // The link's future, made here so a socket that cannot be opened fails before any
    // thread starts.
    enum Running<'sto, F> {
        Emulated(SegmentLink<'sto>),
        Interface(F),
    }
    let running = match link {
        Link::Emulated(segment) => Running::Emulated(SegmentLink::new(tx, rx, segment)),
        Link::Interface(interface) => {
            let fut = ethercrab::std::tx_rx_task(&interface, tx, rx)
                .map_err(|source| SessionError::Interface { interface, source })?;
            Running::Interface(fut)
        }
    };
    std::thread::scope(|s| {
        let link = s.spawn(move || match running {
            Running::Emulated(l) => block_on(l).map_err(|e: LinkError| e.to_string()),
            Running::Interface(f) => block_on(f).map(|_| ()).map_err(|e| e.to_string()),
        });
        // A panic in `run` must still stop the link (else the scope waits for it forever):
        // caught here, re-raised once the link is joined.
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let group = block_on(
                md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercrab::std::ethercat_now),
            )
            .map_err(|source| SessionError::Discovery {
                link: describe.clone(),
                source,
            })?;
            let drive = EcatDrive::bring_up_with(&md, group, config, profiles)
                .map_err(SessionError::BringUp)?;
            Ok(run(drive))
        }));
        // SAFETY: `run` has returned and dropped the drive and its group (the group is
        // never used again), and every exchange waited for its frame or its timeout, so no
        // frame is in flight when the storage is released; the link sees the exit flag
        // and returns.
        let _ = unsafe { md.release_all() };
        let link = link
            .join()
            .map_err(|_| SessionError::Link("the link thread panicked".into()))?;
        let outcome = outcome.unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        match (outcome, link) {
            (Err(e), _) => Err(e),
            (Ok(_), Err(e)) => Err(SessionError::Link(e)),
            (Ok(r), Ok(())) => Ok(r),
        }
    })
}

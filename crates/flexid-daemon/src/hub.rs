//! The event hub of one sweep: what the clients of `GET /api/v1/sweeps/{id}/events` see.
//!
//! Every event is kept in a short history (progress events, the latest `bode` estimate,
//! `result`, `ended`) and broadcast; a client that subscribes gets the history and then the
//! live events, without gaps or duplicates (both happen under one lock).

use super::backend::AbortSignal;
use super::store::SweepStatus;
use std::sync::{Arc, Mutex};
use tokio::sync::broadcast;

/// One server-sent event: its name (`progress`, `bode`, `result`, `ended`) and JSON data.
#[derive(Debug, Clone, PartialEq)]
pub struct HubEvent {
    pub name: &'static str,
    pub data: String,
}

/// Most events kept for late subscribers (older progress events are dropped first).
const HISTORY: usize = 256;

#[derive(Debug)]
struct Inner {
    history: Vec<Arc<HubEvent>>,
    status: SweepStatus,
    ended: bool,
}

/// The hub of one sweep (live in memory while the daemon runs).
#[derive(Debug)]
pub struct SweepHub {
    inner: Mutex<Inner>,
    tx: broadcast::Sender<Arc<HubEvent>>,
    /// Stops the sweep.
    pub abort: AbortSignal,
}

/// What a subscriber receives: the events so far, then the live ones (`None` once ended).
pub struct Subscription {
    pub history: Vec<Arc<HubEvent>>,
    pub live: Option<broadcast::Receiver<Arc<HubEvent>>>,
}

impl SweepHub {
    pub fn new(status: SweepStatus, abort: AbortSignal) -> Self {
        let (tx, _) = broadcast::channel(1024);
        SweepHub {
            inner: Mutex::new(Inner {
                history: Vec::new(),
                status,
                ended: false,
            }),
            tx,
            abort,
        }
    }

    /// Publish an event (a `bode` event replaces the previous one in the history).
    pub fn publish(&self, name: &'static str, data: String) {
        let ev = Arc::new(HubEvent { name, data });
        let Ok(mut g) = self.inner.lock() else {
            return;
        };
        if name == "bode" {
            g.history.retain(|e| e.name != "bode");
        }
        if g.history.len() >= HISTORY {
            if let Some(i) = g.history.iter().position(|e| e.name == "progress") {
                g.history.remove(i);
            }
        }
        g.history.push(ev.clone());
        if name == "ended" {
            g.ended = true;
        }
        let _ = self.tx.send(ev);
    }

    /// Subscribe: the history, and a live receiver unless the sweep has ended.
    pub fn subscribe(&self) -> Subscription {
        match self.inner.lock() {
            Ok(g) => Subscription {
                history: g.history.clone(),
                live: (!g.ended).then(|| self.tx.subscribe()),
            },
            Err(_) => Subscription {
                history: Vec::new(),
                live: None,
            },
        }
    }

    /// The current status.
    pub fn status(&self) -> Option<SweepStatus> {
        self.inner.lock().ok().map(|g| g.status.clone())
    }

    /// Change the status.
    pub fn update(&self, f: impl FnOnce(&mut SweepStatus)) {
        if let Ok(mut g) = self.inner.lock() {
            f(&mut g.status);
        }
    }
}

//! The API's connections: the accept loop, a header-read timeout, a connection limit with
//! per-client fairness, and graceful shutdown (issue 16: about 1000 idle local
//! connections locked the API, and a sweep ending meanwhile lost its result).
//!
//! * Every connection must send a complete request header within
//!   [`HEADER_READ_TIMEOUT`] of being accepted (and of each keep-alive request), else it
//!   is closed.
//! * At most [`Limits::max_connections`] connections are open (by default
//!   [`MAX_CONNECTIONS`], lowered to leave [`FD_RESERVE`] descriptors of the process's
//!   `RLIMIT_NOFILE` to the results store and the backends). A new connection beyond it
//!   closes an idle one (no request in progress) of the client holding the most
//!   connections, its oldest first: a client that floods the daemon with idle
//!   connections loses its own, and everyone else still gets in. When every connection is
//!   busy (streams and downloads in progress), the new one is closed at once.
//! * A client (IP address) may hold at most [`Limits::max_per_client`] connections; one
//!   more closes that client's oldest idle one, or is refused.

use axum::body::Body;
use axum::extract::Request;
use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use std::collections::HashMap;
use std::net::{IpAddr, SocketAddr};
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};
use tokio::net::TcpListener;
use tokio::sync::{watch, Notify};
use tower::ServiceExt;

/// Time a client has to send a complete request header [s].
pub const HEADER_READ_TIMEOUT: Duration = Duration::from_secs(10);

/// Default connection limit.
pub const MAX_CONNECTIONS: usize = 1024;

/// Default limit per client address.
pub const MAX_PER_CLIENT: usize = 512;

/// File descriptors kept free of connections for the store, the backends and the log.
pub const FD_RESERVE: usize = 256;

/// The connection limits in effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Open connections at most.
    pub max_connections: usize,
    /// Open connections per client address at most.
    pub max_per_client: usize,
}

impl Limits {
    /// The defaults, lowered to fit the process's descriptor limit `nofile` (its soft
    /// `RLIMIT_NOFILE`) less [`FD_RESERVE`], and never below 16.
    pub fn for_nofile(nofile: u64) -> Limits {
        let fit = usize::try_from(nofile)
            .unwrap_or(usize::MAX)
            .saturating_sub(FD_RESERVE)
            .max(16);
        let max_connections = MAX_CONNECTIONS.min(fit);
        Limits {
            max_connections,
            max_per_client: MAX_PER_CLIENT.min(max_connections),
        }
    }
}

/// Raise the soft `RLIMIT_NOFILE` to the hard one (systemd's `LimitNOFILE` sets both;
/// a shell's soft limit is often 1024 under a much larger hard one). Returns the soft
/// limit in effect.
pub fn raise_nofile() -> u64 {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit/setrlimit with a valid pointer to a local rlimit.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) != 0 {
            return 1024;
        }
        if lim.rlim_cur < lim.rlim_max {
            let want = libc::rlimit {
                rlim_cur: lim.rlim_max,
                rlim_max: lim.rlim_max,
            };
            if libc::setrlimit(libc::RLIMIT_NOFILE, &want) == 0 {
                lim.rlim_cur = lim.rlim_max;
            }
        }
    }
    lim.rlim_cur
}

struct Conn {
    ip: IpAddr,
    opened: Instant,
    /// Requests in progress (a response body not yet sent counts).
    busy: Arc<AtomicUsize>,
    close: Arc<Notify>,
}

/// The open connections.
#[derive(Default)]
struct Table {
    conns: Mutex<HashMap<u64, Conn>>,
    next: AtomicU64,
}

enum Admit {
    Yes,
    /// Admitted after closing this idle connection.
    Evict(Arc<Notify>),
    No(&'static str),
}

impl Table {
    fn len(&self) -> usize {
        self.conns.lock().map(|c| c.len()).unwrap_or(0)
    }

    /// Whether a new connection from `ip` may open under `limits`, and which idle one to
    /// close for it.
    fn admit(&self, ip: IpAddr, limits: &Limits) -> Admit {
        let Ok(mut conns) = self.conns.lock() else {
            return Admit::No("connection table poisoned");
        };
        let mut per_ip: HashMap<IpAddr, usize> = HashMap::new();
        for c in conns.values() {
            *per_ip.entry(c.ip).or_default() += 1;
        }
        let idle_oldest = |of: IpAddr| {
            conns
                .iter()
                .filter(|(_, c)| c.ip == of && c.busy.load(Ordering::SeqCst) == 0)
                .min_by_key(|(_, c)| c.opened)
                .map(|(id, _)| *id)
        };
        let victim = if per_ip.get(&ip).copied().unwrap_or(0) >= limits.max_per_client {
            match idle_oldest(ip) {
                Some(id) => id,
                None => return Admit::No("per-client limit reached, all its connections busy"),
            }
        } else if conns.len() < limits.max_connections {
            return Admit::Yes;
        } else {
            // the client with the most connections that has an idle one loses its oldest
            let mut clients: Vec<(IpAddr, usize)> = per_ip.into_iter().collect();
            clients.sort_by_key(|c| std::cmp::Reverse(c.1));
            match clients
                .into_iter()
                .find_map(|(client, _)| idle_oldest(client))
            {
                Some(id) => id,
                None => return Admit::No("connection limit reached, all connections busy"),
            }
        };
        // out of the table at once: the next admission counts without it
        match conns.remove(&victim) {
            Some(c) => Admit::Evict(c.close),
            None => Admit::No("connection table changed"),
        }
    }

    fn insert(&self, ip: IpAddr) -> (u64, Arc<AtomicUsize>, Arc<Notify>) {
        let id = self.next.fetch_add(1, Ordering::Relaxed);
        let busy = Arc::new(AtomicUsize::new(0));
        let close = Arc::new(Notify::new());
        if let Ok(mut c) = self.conns.lock() {
            c.insert(
                id,
                Conn {
                    ip,
                    opened: Instant::now(),
                    busy: busy.clone(),
                    close: close.clone(),
                },
            );
        }
        (id, busy, close)
    }

    fn remove(&self, id: u64) {
        if let Ok(mut c) = self.conns.lock() {
            c.remove(&id);
        }
    }
}

/// Connections the kernel queues for `accept` (capped by `net.core.somaxconn`). Tokio and
/// the standard library listen with 128: a burst of connects (the load test opens 100 at
/// once while the accept loop evicts idle ones) overflowed it, the kernel dropped SYNs
/// (`TcpExtListenOverflows`) and a fresh API request waited for the client's 1 s SYN
/// retransmission. A queue as long as the default connection limit holds such a burst.
pub const LISTEN_BACKLOG: u32 = MAX_CONNECTIONS as u32;

/// Bind the API's listening socket at `addr` with [`LISTEN_BACKLOG`].
pub fn bind(addr: SocketAddr) -> std::io::Result<TcpListener> {
    let socket = match addr {
        SocketAddr::V4(_) => tokio::net::TcpSocket::new_v4()?,
        SocketAddr::V6(_) => tokio::net::TcpSocket::new_v6()?,
    };
    socket.set_reuseaddr(true)?;
    socket.bind(addr)?;
    socket.listen(LISTEN_BACKLOG)
}

/// Serve `app` on `listener` under `limits` until `stop` turns true; then stop accepting,
/// let every connection finish its request in progress, and return when all are closed.
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: Limits,
    mut stop: watch::Receiver<bool>,
) -> std::io::Result<()> {
    let table = Arc::new(Table::default());
    let mut refused_logged = Instant::now() - Duration::from_secs(60);
    loop {
        let accepted = tokio::select! {
            a = listener.accept() => a,
            _ = stop.wait_for(|s| *s) => break,
        };
        let (stream, peer) = match accepted {
            Ok(x) => x,
            Err(e) => {
                // EMFILE/ENFILE and the like: log, pause briefly, go on (axum does the same)
                tracing::warn!("api: accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(20)).await;
                continue;
            }
        };
        match table.admit(peer.ip(), &limits) {
            Admit::Yes => {}
            Admit::Evict(close) => close.notify_one(),
            Admit::No(why) => {
                if refused_logged.elapsed() > Duration::from_secs(10) {
                    tracing::warn!(
                        "api: connection from {peer} refused: {why} ({} open)",
                        table.len()
                    );
                    refused_logged = Instant::now();
                }
                drop(stream);
                continue;
            }
        }
        let _ = stream.set_nodelay(true);
        let (id, busy, close) = table.insert(peer.ip());
        let app = app.clone();
        let table = table.clone();
        let stop = stop.clone();
        tokio::spawn(async move {
            serve_one(stream, peer, app, busy, close, stop).await;
            table.remove(id);
        });
    }
    // graceful: wait for the connections to finish (the caller bounds the wait)
    while table.len() > 0 {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    Ok(())
}

async fn serve_one(
    stream: tokio::net::TcpStream,
    peer: SocketAddr,
    app: Router,
    busy: Arc<AtomicUsize>,
    close: Arc<Notify>,
    mut stop: watch::Receiver<bool>,
) {
    let service = hyper::service::service_fn(move |mut req: Request<hyper::body::Incoming>| {
        let app = app.clone();
        let guard = BusyGuard::new(busy.clone());
        req.extensions_mut()
            .insert(axum::extract::ConnectInfo(peer));
        async move {
            let req = req.map(Body::new);
            let resp = app.oneshot(req).await.unwrap_or_else(|e| match e {});
            // the connection stays busy until the whole body is sent (event streams)
            Ok::<_, std::convert::Infallible>(resp.map(|b| {
                Body::new(GuardedBody {
                    inner: b,
                    _guard: guard,
                })
            }))
        }
    });
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(HEADER_READ_TIMEOUT);
    let conn = builder.serve_connection(TokioIo::new(stream), service);
    let mut conn = std::pin::pin!(conn);
    tokio::select! {
        r = conn.as_mut() => {
            if let Err(e) = r {
                tracing::debug!("api: connection {peer}: {e}");
            }
            return;
        }
        _ = close.notified() => {
            tracing::debug!("api: connection {peer} closed to admit another");
            return;
        }
        _ = stop.wait_for(|s| *s) => {}
    }
    // shutdown: finish the request in progress, then close
    conn.as_mut().graceful_shutdown();
    let _ = conn.await;
}

/// Counts a request in progress on its connection while alive.
struct BusyGuard(Arc<AtomicUsize>);

impl BusyGuard {
    fn new(busy: Arc<AtomicUsize>) -> BusyGuard {
        busy.fetch_add(1, Ordering::SeqCst);
        BusyGuard(busy)
    }
}

impl Drop for BusyGuard {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A response body that keeps its connection counted busy until it is sent or dropped.
struct GuardedBody {
    inner: Body,
    _guard: BusyGuard,
}

impl http_body::Body for GuardedBody {
    type Data = axum::body::Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>> {
        Pin::new(&mut self.inner).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_leave_descriptors_to_the_store() {
        assert_eq!(Limits::for_nofile(1024).max_connections, 768);
        assert_eq!(Limits::for_nofile(65536).max_connections, MAX_CONNECTIONS);
        assert_eq!(Limits::for_nofile(100).max_connections, 16);
        let l = Limits::for_nofile(300);
        assert!(l.max_per_client <= l.max_connections);
    }

    /// A burst of 300 connects to a listener that is not accepting: all are queued by the
    /// kernel (with tokio's default backlog 128, about 129 complete and the rest wait for
    /// a SYN retransmission, which made a fresh API request take 1 s in the load test).
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_burst_of_connects_is_queued_not_dropped() {
        const BURST: usize = 300;
        let somaxconn: usize = std::fs::read_to_string("/proc/sys/net/core/somaxconn")
            .ok()
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(0);
        if somaxconn < BURST {
            eprintln!("skipped: net.core.somaxconn {somaxconn} < {BURST} caps every backlog");
            return;
        }
        let listener = bind("127.0.0.1:0".parse().unwrap()).unwrap();
        let addr = listener.local_addr().unwrap();
        let mut tasks = Vec::new();
        for _ in 0..BURST {
            tasks.push(tokio::spawn(async move {
                tokio::time::timeout(
                    Duration::from_millis(700),
                    tokio::net::TcpStream::connect(addr),
                )
                .await
            }));
        }
        let mut connected = Vec::new();
        for t in tasks {
            if let Ok(Ok(s)) = t.await.unwrap() {
                connected.push(s);
            }
        }
        assert_eq!(connected.len(), BURST, "connects completed without accept");
        drop(listener);
    }

    /// The client with the most connections loses its oldest idle one; a busy one is
    /// never closed; with everything busy a new connection is refused.
    #[test]
    fn the_flooding_client_loses_its_oldest_idle_connection() {
        let t = Table::default();
        let flood: IpAddr = "10.0.0.9".parse().unwrap();
        let other: IpAddr = "10.0.0.1".parse().unwrap();
        let limits = Limits {
            max_connections: 4,
            max_per_client: 3,
        };
        let (_, b0, _) = t.insert(other);
        b0.fetch_add(1, Ordering::SeqCst); // busy: an event stream
        let mut closes = Vec::new();
        for _ in 0..3 {
            assert!(matches!(t.admit(flood, &limits), Admit::Yes));
            closes.push(t.insert(flood).2);
        }
        // a fourth from the flooder: over its own limit, its oldest idle goes
        match t.admit(flood, &limits) {
            Admit::Evict(n) => assert!(Arc::ptr_eq(&n, &closes[0])),
            _ => panic!("expected the flooder's oldest to be closed"),
        }
        t.insert(flood);
        // another client at the total limit: the flooder loses one, not the busy stream
        match t.admit(other, &limits) {
            Admit::Evict(n) => assert!(Arc::ptr_eq(&n, &closes[1])),
            _ => panic!("expected an eviction"),
        }
        // all busy: refused
        let t2 = Table::default();
        let one = Limits {
            max_connections: 1,
            max_per_client: 1,
        };
        let (_, b, _) = t2.insert(other);
        b.fetch_add(1, Ordering::SeqCst);
        assert!(matches!(t2.admit(flood, &one), Admit::No(_)));
    }
}

//! MQTT publishing (rumqttc): retained messages `<prefix>/<axis>/model` (the identified
//! parameters) and `<prefix>/<axis>/state` (the axis state). Publishing never blocks the
//! caller: messages go through a queue to a task that owns the connection and reconnects.

use super::config::MqttConfig;
use rumqttc::{AsyncClient, MqttOptions, QoS};
use std::time::Duration;
use tokio::sync::{mpsc, watch};

/// A handle for publishing (cheap to clone).
#[derive(Debug, Clone)]
pub struct Mqtt {
    tx: mpsc::UnboundedSender<(String, Vec<u8>)>,
    prefix: String,
}

impl Mqtt {
    /// Start the connection task. It ends when `shutdown` turns true (after sending what
    /// is queued, within a second).
    pub fn start(cfg: &MqttConfig, mut shutdown: watch::Receiver<bool>) -> Mqtt {
        let id = cfg
            .client_id
            .clone()
            .unwrap_or_else(|| format!("flexid-{}", std::process::id()));
        let mut opts = MqttOptions::new(id, cfg.host.clone(), cfg.port);
        opts.set_keep_alive(Duration::from_secs(30));
        let (client, mut eventloop) = AsyncClient::new(opts, 64);
        let (tx, mut rx) = mpsc::unbounded_channel::<(String, Vec<u8>)>();
        let host = format!("{}:{}", cfg.host, cfg.port);
        tokio::spawn(async move {
            let mut connected = false;
            let mut warn_every = Throttle::new(Duration::from_secs(60));
            loop {
                tokio::select! {
                    ev = eventloop.poll() => match ev {
                        Ok(rumqttc::Event::Incoming(rumqttc::Packet::ConnAck(_))) => {
                            connected = true;
                            tracing::info!("mqtt: connected to {host}");
                        }
                        Ok(_) => {}
                        Err(e) => {
                            if connected {
                                tracing::warn!("mqtt: {host}: {e}; reconnecting");
                            } else if warn_every.due(std::time::Instant::now()) {
                                // issue 16: a broker never reached was logged at debug only
                                tracing::warn!("mqtt: cannot connect to {host}: {e}; retrying every second (this warning at most once a minute)");
                            } else {
                                tracing::debug!("mqtt: {host}: {e}; retrying");
                            }
                            connected = false;
                            tokio::time::sleep(Duration::from_secs(1)).await;
                        }
                    },
                    msg = rx.recv() => match msg {
                        Some((topic, payload)) => {
                            if let Err(e) = client.try_publish(topic.clone(), QoS::AtLeastOnce, true, payload) {
                                tracing::warn!("mqtt: {topic}: {e}");
                            }
                        }
                        None => break,
                    },
                    _ = shutdown.changed() => {
                        if *shutdown.borrow() {
                            // give queued publications a moment to leave
                            let _ = tokio::time::timeout(Duration::from_secs(1), async {
                                loop { if eventloop.poll().await.is_err() { break; } }
                            }).await;
                            let _ = client.try_disconnect();
                            break;
                        }
                    }
                }
            }
        });
        Mqtt {
            tx,
            prefix: cfg.topic_prefix.clone(),
        }
    }

    /// Topic `<prefix>/<axis>/<leaf>`.
    pub fn topic(&self, axis: &str, leaf: &str) -> String {
        format!("{}/{axis}/{leaf}", self.prefix)
    }

    /// Queue a retained message for `<prefix>/<axis>/<leaf>` (QoS 1).
    pub fn publish(&self, axis: &str, leaf: &str, payload: &serde_json::Value) {
        let topic = self.topic(axis, leaf);
        let bytes = payload.to_string().into_bytes();
        let _ = self.tx.send((topic, bytes));
    }
}

/// At most one warning per interval: the first call is due, then one per `every`.
#[derive(Debug)]
pub struct Throttle {
    every: Duration,
    last: Option<std::time::Instant>,
}

impl Throttle {
    pub fn new(every: Duration) -> Throttle {
        Throttle { every, last: None }
    }

    /// Whether a warning is due at `now` (and, if so, note it).
    pub fn due(&mut self, now: std::time::Instant) -> bool {
        if self
            .last
            .is_some_and(|t| now.duration_since(t) < self.every)
        {
            return false;
        }
        self.last = Some(now);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A connection that never succeeds warns at once and then once a minute.
    #[test]
    fn a_failed_connection_warns_at_once_then_once_a_minute() {
        let mut t = Throttle::new(Duration::from_secs(60));
        let t0 = std::time::Instant::now();
        assert!(t.due(t0));
        assert!(!t.due(t0 + Duration::from_secs(1)));
        assert!(!t.due(t0 + Duration::from_secs(59)));
        assert!(t.due(t0 + Duration::from_secs(61)));
    }
}

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

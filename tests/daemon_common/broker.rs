//! A real MQTT broker for the daemon tests: Debian's `mosquitto`, started on a free
//! loopback port with a temporary configuration, and a reader of retained messages.

use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

fn mosquitto_path() -> Option<std::path::PathBuf> {
    [
        "/usr/sbin/mosquitto",
        "/usr/bin/mosquitto",
        "/usr/local/sbin/mosquitto",
    ]
    .iter()
    .map(std::path::PathBuf::from)
    .find(|p| p.exists())
}

/// A running mosquitto, killed on drop.
pub struct Broker {
    pub child: Child,
    pub port: u16,
}

impl Drop for Broker {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Start mosquitto on a free loopback port (`None`: not installed, skip; panics under
/// `CI=true`).
pub fn start_broker(dir: &std::path::Path) -> Option<Broker> {
    let Some(bin) = mosquitto_path() else {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!(
                "mosquitto is not installed (required under CI=true; scripts/test.sh installs it)"
            );
        }
        eprintln!("skipped: mosquitto is not installed (apt-get install mosquitto)");
        return None;
    };
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let conf = dir.join("mosquitto.conf");
    std::fs::write(
        &conf,
        format!("listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n"),
    )
    .unwrap();
    let child = Command::new(bin)
        .arg("-c")
        .arg(&conf)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let broker = Broker { child, port };
    let t0 = std::time::Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "mosquitto did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    Some(broker)
}

/// Subscribe to `topic` and return the first retained message's JSON.
pub async fn read_retained(port: u16, topic: &str) -> serde_json::Value {
    let mut opts = MqttOptions::new(format!("test-{}", std::process::id()), "127.0.0.1", port);
    opts.set_keep_alive(Duration::from_secs(5));
    let (client, mut el) = AsyncClient::new(opts, 10);
    client.subscribe(topic, QoS::AtLeastOnce).await.unwrap();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(15);
    loop {
        let Ok(ev) = tokio::time::timeout_at(deadline, el.poll()).await else {
            panic!("no retained message on {topic}");
        };
        let ev = ev.unwrap();
        if let Event::Incoming(Packet::Publish(p)) = ev {
            assert!(p.retain, "{topic}: not retained");
            assert_eq!(p.topic, topic);
            return serde_json::from_slice(&p.payload).unwrap();
        }
    }
}

/// The retained message of `topic` whose `sweep_id` is `id`: the daemon publishes the
/// model after the sweep's `ended` event, so a subscription made at `ended` may see the
/// previous retained message or the live one first; subscribes again (a new client) until
/// the retained message is this sweep's, for up to 15 s.
pub async fn read_retained_of(port: u16, topic: &str, id: &str) -> serde_json::Value {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(15);
    for attempt in 0u32.. {
        let mut opts = MqttOptions::new(
            format!("test-{}-{attempt}", std::process::id()),
            "127.0.0.1",
            port,
        );
        opts.set_keep_alive(Duration::from_secs(5));
        let (client, mut el) = AsyncClient::new(opts, 10);
        client.subscribe(topic, QoS::AtLeastOnce).await.unwrap();
        let until = (tokio::time::Instant::now() + Duration::from_secs(1)).min(deadline);
        while let Ok(ev) = tokio::time::timeout_at(until, el.poll()).await {
            if let Event::Incoming(Packet::Publish(p)) = ev.unwrap() {
                let v: serde_json::Value = serde_json::from_slice(&p.payload).unwrap();
                if p.retain && p.topic == topic && v["sweep_id"] == id {
                    return v;
                }
            }
        }
        let _ = client.disconnect().await;
        if tokio::time::Instant::now() >= deadline {
            break;
        }
    }
    panic!("no retained message of sweep {id} on {topic} within 15 s");
}

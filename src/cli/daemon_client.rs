//! `flexid sweep --daemon URL`: the same sweep, run by a running `flexid daemon` (which owns
//! the bus) instead of in this process. The flags become a sweep request for the daemon's
//! axis; the event stream drives a progress bar; the results are downloaded into `--out`
//! and the identified parameters printed as a table. Ctrl-C aborts the sweep on the daemon.

use super::sweep_args::{ExcitationArg, SweepArgs};
use super::CliError;
use futures_util::StreamExt;
use serde_json::{json, Value};
use std::time::Duration;

pub use super::sweep_args::DaemonClientArgs;

/// Files of a finished sweep written into `--out` (the daemon's names).
const FILES: [&str; 4] = ["recording.csv", "recording.json", "frf.csv", "bode.svg"];

/// Which flag a field of the daemon's request error comes from.
fn flag_of(field: &str) -> &'static str {
    match field {
        "excitation" => "--excitation",
        "band_hz" => "--band",
        "amplitude_nm" => "--peak-nm",
        "periods" => "--periods",
        "duration_s" => "--periods/--resolution-hz",
        _ => "the request",
    }
}

struct Client {
    base: String,
    token: String,
    http: reqwest::Client,
}

impl Client {
    fn req(&self, method: reqwest::Method, path: &str) -> reqwest::RequestBuilder {
        self.http
            .request(method, format!("{}{path}", self.base))
            .bearer_auth(&self.token)
    }

    /// A request whose answer must be 2xx; a daemon error becomes a [`CliError`] (exit 2 for
    /// a refused request, 1 otherwise).
    async fn send(&self, rb: reqwest::RequestBuilder) -> Result<reqwest::Response, CliError> {
        let r = rb
            .send()
            .await
            .map_err(|e| CliError::failed(format!("daemon {}: {e}", self.base)))?;
        if r.status().is_success() {
            return Ok(r);
        }
        let status = r.status();
        let v: Value = r.json().await.unwrap_or(Value::Null);
        let msg = v["error"].as_str().unwrap_or("no message").to_string();
        let msg = match v["field"].as_str() {
            Some(f) => format!("daemon refused {}: {msg}", flag_of(f)),
            None => format!("daemon: {msg} (HTTP {})", status.as_u16()),
        };
        Err(if status.is_client_error() {
            CliError::input(msg)
        } else {
            CliError::failed(msg)
        })
    }

    async fn json(&self, path: &str) -> Result<Value, CliError> {
        let r = self.send(self.req(reqwest::Method::GET, path)).await?;
        r.json()
            .await
            .map_err(|e| CliError::failed(format!("daemon {path}: {e}")))
    }
}

/// The flags the daemon cannot honour (its axis configuration decides those), as an error.
fn refuse_local_only(a: &SweepArgs) -> Result<(), CliError> {
    let local = [
        (a.rms_nm.is_some(), "--rms-nm"),
        (
            a.transient_periods != 1,
            "--transient-periods (the daemon uses 1)",
        ),
        (a.amplitude_exponent != 0.0, "--amplitude-exponent"),
        (a.masses.is_some(), "--masses"),
        (
            a.max_lost.is_some(),
            "--max-lost (the daemon's axis configuration sets it)",
        ),
        (
            a.profiles.is_some(),
            "--profiles (the daemon's axes name theirs)",
        ),
    ];
    match local.iter().find(|(set, _)| *set) {
        Some((_, flag)) => Err(CliError::input(format!(
            "{flag} cannot be used with --daemon"
        ))),
        None => Ok(()),
    }
}

/// The sweep request of the flags for an axis of `cycle_hz`.
pub fn request_body(a: &SweepArgs, cycle_hz: f64) -> Value {
    let band = a
        .band
        .clone()
        .unwrap_or_else(|| vec![a.resolution_hz, 0.4 * cycle_hz]);
    json!({
        "excitation": match a.excitation {
            ExcitationArg::Multisine => "multisine",
            ExcitationArg::Chirp => "chirp",
        },
        "band_hz": band,
        "amplitude_nm": a.peak_nm,
        "periods": a.periods,
        // one transient period plus the measured ones, each 1 / resolution long
        "duration_s": (a.periods + 1) as f64 / a.resolution_hz,
    })
}

/// The axis of the daemon that the flags name.
fn pick_axis(axes: &[Value], a: &SweepArgs) -> Result<Value, CliError> {
    let names = || {
        axes.iter()
            .map(|x| format!("{} (node {})", x["name"].as_str().unwrap_or("?"), x["node"]))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let found: Vec<&Value> = match &a.daemon.axis {
        Some(name) => axes.iter().filter(|x| x["name"] == name.as_str()).collect(),
        None => axes
            .iter()
            .filter(|x| x["node"].as_u64() == Some(u64::from(a.node)))
            .collect(),
    };
    match found.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(CliError::input(format!(
            "the daemon has no axis {}; it has: {}",
            a.daemon
                .axis
                .clone()
                .unwrap_or_else(|| format!("with --node {}", a.node)),
            names()
        ))),
        _ => Err(CliError::input(format!(
            "several axes of the daemon have node {}: name one with --axis ({})",
            a.node,
            names()
        ))),
    }
}

/// `flexid sweep --daemon URL`.
pub fn sweep_via_daemon(a: &SweepArgs, url: &str) -> Result<(), CliError> {
    refuse_local_only(a)?;
    let token = std::fs::read_to_string(&a.daemon.token_file)
        .map_err(|e| CliError::input(format!("{}: {e}", a.daemon.token_file.display())))?
        .trim()
        .to_string();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| CliError::failed(e.to_string()))?;
    let http = reqwest::Client::builder()
        .connect_timeout(Duration::from_secs(5))
        .build()
        .map_err(|e| CliError::failed(e.to_string()))?;
    let client = Client {
        base: url.trim_end_matches('/').to_string(),
        token,
        http,
    };
    rt.block_on(run(&client, a))
}

async fn run(c: &Client, a: &SweepArgs) -> Result<(), CliError> {
    let axes = c.json("/api/v1/axes").await?;
    let axes = axes["axes"].as_array().cloned().unwrap_or_default();
    let axis = pick_axis(&axes, a)?;
    let name = axis["name"].as_str().unwrap_or_default().to_string();
    let body = request_body(a, axis["cycle_hz"].as_f64().unwrap_or(a.cycle_hz));
    eprintln!(
        "flexid sweep: through the daemon at {}, axis {name}: {body}",
        c.base
    );
    let started: Value = c
        .send(
            c.req(
                reqwest::Method::POST,
                &format!("/api/v1/axes/{name}/sweeps"),
            )
            .json(&body),
        )
        .await?
        .json()
        .await
        .map_err(|e| CliError::failed(e.to_string()))?;
    let id = started["sweep_id"].as_str().unwrap_or_default().to_string();
    eprintln!("flexid sweep: sweep {id} started (Ctrl-C aborts it)");
    let ended = tokio::select! {
        r = follow(c, &id) => r?,
        _ = tokio::signal::ctrl_c() => {
            eprintln!("flexid sweep: aborting sweep {id}");
            c.send(c.req(reqwest::Method::POST, &format!("/api/v1/sweeps/{id}/abort"))).await?;
            follow(c, &id).await?
        }
    };
    // the results into --out, as the in-process sweep writes them
    std::fs::create_dir_all(&a.out)
        .map_err(|e| CliError::failed(format!("{}: {e}", a.out.display())))?;
    let status = c.json(&format!("/api/v1/sweeps/{id}")).await?;
    for f in FILES {
        if let Ok(r) = c
            .send(c.req(reqwest::Method::GET, &format!("/api/v1/sweeps/{id}/{f}")))
            .await
        {
            let bytes = r
                .bytes()
                .await
                .map_err(|e| CliError::failed(e.to_string()))?;
            write(&a.out.join(f), &bytes)?;
        }
    }
    if !status["result"].is_null() {
        let text = serde_json::to_string_pretty(&status["result"]).unwrap_or_default();
        write(&a.out.join("result.json"), text.as_bytes())?;
    }
    let outcome = ended["outcome"].as_str().unwrap_or("unknown");
    let model = &status["result"]["model"];
    if !model.is_null() {
        print!("{}", parameter_table(model));
    }
    eprintln!(
        "flexid sweep: {outcome} ({}), {} samples; wrote {}",
        ended["reason"].as_str().unwrap_or("-"),
        ended["samples"],
        a.out.display()
    );
    match (outcome, model.is_null()) {
        ("completed", false) => Ok(()),
        ("completed", true) => Err(CliError::failed(
            "the sweep completed but no model was identified",
        )),
        _ => Err(CliError::failed(format!(
            "sweep {outcome}: {}; the samples measured are saved in {}",
            ended["reason"].as_str().unwrap_or("-"),
            a.out.display()
        ))),
    }
}

fn write(path: &std::path::Path, bytes: &[u8]) -> Result<(), CliError> {
    std::fs::write(path, bytes).map_err(|e| CliError::failed(format!("{}: {e}", path.display())))
}

/// Read the event stream until `ended` (returned), showing the progress: a bar on a
/// terminal, one line per period otherwise.
async fn follow(c: &Client, id: &str) -> Result<Value, CliError> {
    let r = c
        .send(c.req(reqwest::Method::GET, &format!("/api/v1/sweeps/{id}/events")))
        .await?;
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40.cyan/blue} period {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let plain = bar.is_hidden();
    let mut stream = r.bytes_stream();
    let mut buf = String::new();
    while let Some(chunk) = stream.next().await {
        let chunk = chunk.map_err(|e| CliError::failed(format!("event stream: {e}")))?;
        buf.push_str(&String::from_utf8_lossy(&chunk));
        while let Some(end) = buf.find("\n\n") {
            let block: String = buf.drain(..end + 2).collect();
            let Some((name, data)) = parse_event(&block) else {
                continue;
            };
            match name.as_str() {
                "progress" => {
                    let (p, n) = (data["period"].as_u64(), data["periods_total"].as_u64());
                    bar.set_length(n.unwrap_or(1));
                    bar.set_position(p.unwrap_or(0));
                    let msg = format!(
                        "{:.1}/{:.1} s",
                        data["elapsed_s"].as_f64().unwrap_or(0.0),
                        data["planned_s"].as_f64().unwrap_or(0.0)
                    );
                    if plain {
                        eprintln!(
                            "flexid sweep: period {}/{} {msg}",
                            p.unwrap_or(0),
                            n.unwrap_or(0)
                        );
                    }
                    bar.set_message(msg);
                }
                "bode" if plain => eprintln!(
                    "flexid sweep: Bode estimate after period {} ({} lines)",
                    data["period"],
                    data["freq_hz"].as_array().map_or(0, |f| f.len())
                ),
                "ended" => {
                    bar.finish_and_clear();
                    return Ok(data);
                }
                _ => {}
            }
        }
    }
    bar.finish_and_clear();
    Err(CliError::failed(
        "the daemon closed the event stream before the sweep ended",
    ))
}

fn parse_event(block: &str) -> Option<(String, Value)> {
    let mut name = String::from("message");
    let mut data = String::new();
    for line in block.lines() {
        if let Some(v) = line.strip_prefix("event:") {
            name = v.trim().to_string();
        } else if let Some(v) = line.strip_prefix("data:") {
            data.push_str(v.trim_start());
        }
    }
    serde_json::from_str(&data).ok().map(|d| (name, d))
}

/// The identified parameters with their one-sigma uncertainty, one per line.
pub fn parameter_table(model: &Value) -> String {
    let mut out = format!(
        "identified chain: {} masses (motor is body 1)\n{:<10} {:>14} {:>14} {:>8}  unit\n",
        model["masses"], "parameter", "value", "1-sigma", "rel"
    );
    let groups = [
        ("J", "inertia_kgm2", "inertia_std_kgm2", "kg m^2"),
        (
            "c",
            "stiffness_nm_per_rad",
            "stiffness_std_nm_per_rad",
            "N m/rad",
        ),
        (
            "d",
            "damping_nms_per_rad",
            "damping_std_nms_per_rad",
            "N m s/rad",
        ),
    ];
    for (sym, key, std_key, unit) in groups {
        let vals = model[key].as_array().cloned().unwrap_or_default();
        for (i, v) in vals.iter().enumerate() {
            let name = format!("{sym}{}", i + 1);
            // null (or an uncertainty above the value): not identifiable from the data
            match (v.as_f64(), model[std_key][i].as_f64()) {
                (Some(v), Some(s)) if s.is_finite() && s <= v.abs() => {
                    out += &format!(
                        "{name:<10} {v:>14.6e} {s:>14.3e} {:>7.2}%  {unit}\n",
                        100.0 * s / v.abs()
                    );
                }
                _ => {
                    out += &format!(
                        "{name:<10} {:>14} {:>14} {:>8}  {unit}\n",
                        "not identifiable", "", ""
                    )
                }
            }
        }
    }
    let hz = |k: &str| {
        model[k]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(Value::as_f64)
                    .map(|f| format!("{f:.2}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default()
    };
    out += &format!(
        "resonances [Hz]: {}\nanti-resonances [Hz]: {}\n",
        hz("resonance_hz"),
        hz("antiresonance_hz")
    );
    out
}

//! Bad daemon configurations, through `flexid daemon --config`: exit 2 and the key,
//! before anything is bound or started.

use super::cases::{assert_all_held, run_cases, Case};

pub const KINDS: usize = 12;

/// A valid configuration with the token file `token` beside it (mode 0600 is set by the
/// case runner through [`token_case`]); `{data}` is the data folder.
fn good() -> String {
    r#"data_dir = "data"
[api]
listen = "127.0.0.1:0"
token_file = "token"
[[bus]]
name = "vbus"
kind = "udp"
group = "239.74.163.2"
port = 43113
bitrate = 1000000
[[axis]]
name = "a1"
bus = "vbus"
node = 1
cycle_hz = 1000
clock = "simulated"
limits = { peak_torque_nm = 1.0, max_speed_rad_s = 100.0, position_window_rad = 10.0, max_sweep_s = 60 }
"#
    .to_string()
}

fn config(name: &'static str, text: &str, says: &[&str]) -> Case {
    Case::new(name, &["daemon", "--config", "flexid.toml"], 2, says)
        .file("flexid.toml", text.as_bytes().to_vec())
}

pub fn cases() -> Vec<Case> {
    let g = good();
    vec![
        config("not TOML", "data_dir = \n[api", &["flexid.toml"]),
        config("an unknown key", &g.replace("[api]", "[api]\nlisten_on = \"x\""), &["flexid.toml", "listen_on"]),
        config("a listen address that is no address", &g.replace("127.0.0.1:0", "localhost-ish"), &["flexid.toml", "listen"]),
        config("a token file that is not there", &g.replace("token_file = \"token\"", "token_file = \"nope\""), &["nope"]),
        config("a zero peak torque", &g.replace("peak_torque_nm = 1.0", "peak_torque_nm = 0.0"), &["axis[0].limits.peak_torque_nm"]),
        config("a negative cycle rate", &g.replace("cycle_hz = 1000", "cycle_hz = -1000"), &["axis[0].cycle_hz"]),
        config("a bitrate of zero", &g.replace("bitrate = 1000000", "bitrate = 0"), &["bus[0].bitrate"]),
        config("an axis on a bus that does not exist", &g.replace("bus = \"vbus\"", "bus = \"nobus\""), &["axis[0].bus", "no [[bus]] has this name"]),
        config("two axes of one name", &format!("{g}[[axis]]\nname = \"a1\"\nbus = \"vbus\"\nnode = 2\ncycle_hz = 1000\nclock = \"simulated\"\nlimits = {{ peak_torque_nm = 1.0, max_speed_rad_s = 100.0, position_window_rad = 10.0, max_sweep_s = 60 }}\n"), &["axis[1].name", "duplicate"]),
        config("an unknown clock", &g.replace("clock = \"simulated\"", "clock = \"sundial\""), &["sundial"]),
        config("a node id of 300", &g.replace("node = 1", "node = 300"), &["axis[0].node"]),
        Case::new("a configuration that is a folder", &["daemon", "--config", "."], 2, &["not a regular file"]),
    ]
}

#[test]
fn bad_configurations() {
    let cases = cases();
    assert_eq!(cases.len(), KINDS);
    assert_all_held("daemon configurations", &run_cases(&cases));
}

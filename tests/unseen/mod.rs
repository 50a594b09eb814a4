//! Cases of the benchmark "identification on data it was never tuned on"
//! (`benches/identify_unseen.rs`), shared with the test that checks every output of them
//! for numbers that must never be printed (`tests/identify_unseen.rs`): random chains of
//! 2 to 5 masses simulated by the fine-step plant (not the fit's sampled model), with the
//! truth and how well the data can show each pair.
#![allow(dead_code)]

use flexid::analysis::{to_json, Analysis};
use flexid::excitation::{AmplitudeShape, ExcitationInfo, MultisineDesign, PhaseDesign};
use flexid::model::Chain;
use flexid::plant::{run, Effects, PlantSim, PlantSpec};
use flexid::plot::BodePlot;
use flexid::recording::Recording;
use flexid::report::render_report;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// One generated case: the recording and the truth.
pub struct Case {
    pub rec: Recording,
    pub chain: Chain,
    pub describe: String,
    /// Per true pair (frequency order): how well the data can show it.
    pub visibility: Vec<Visibility>,
    /// `(gain2, rms, q, s_w)` of [`visibility`].
    pub noise_model: (f64, f64, f64, f64),
}

/// How well a true pair can be seen in the recording, from what only the simulator knows
/// (the true response, the excitation's power, the encoder step and the disturbance),
/// independently of the tool: the FRF's signal-to-noise ratio per line at 0.5 Hz
/// resolution, `SNR^2 = |H|^2 S_u T df / S_e`, its median over the lines from 10 % below
/// the pair's anti-resonance to 10 % above its resonance, and its largest value within
/// 1 % of the resonance (the peak). (Checked against the tool's own line variance: the
/// two agree within about 25 %.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Visibility {
    /// Median SNR >= 10: the tool must find the pair, both frequencies within 2 %.
    Visible,
    /// Median SNR < 10 but the peak's >= 2: finding it (its resonance within 2 %; its
    /// notch is not resolved) or saying nothing are both accepted.
    Marginal,
    /// Even the peak's SNR < 2: no information; a pair placed there is wrong.
    Hidden,
}

/// The visibility of each of `chain`'s pairs. `gain2` is `S_u T df / (r^2)`-free factor:
/// `SNR^2 = gain2 |H_pos|^2 r^2 / v(f)` with `v = q^2/12 + |H_pos|^2 s_w^2` the position
/// noise per sample (encoder step `q` [rad], disturbance torque `s_w` [N m]).
pub fn visibility(chain: &Chain, gain2: f64, rms: f64, q: f64, s_w: f64) -> Vec<Visibility> {
    let snr = |f: f64| {
        let hp = chain.mobility(f).norm() / (2.0 * std::f64::consts::PI * f);
        let v = q * q / 12.0 + hp * hp * s_w * s_w;
        (gain2 * hp * hp * rms * rms / v).sqrt()
    };
    chain
        .antiresonances_hz()
        .iter()
        .zip(chain.resonances_hz())
        .map(|(&a, r)| {
            let (lo, hi) = (a / 1.1, r * 1.1);
            let mut v: Vec<f64> = (0..)
                .map(|k| lo + 0.5 * k as f64)
                .take_while(|f| *f <= hi)
                .map(snr)
                .collect();
            let peak = (0..=20)
                .map(|k| snr(r * (0.99 + 0.001 * k as f64)))
                .fold(0.0, f64::max);
            v.sort_by(f64::total_cmp);
            let m = v[v.len() / 2];
            if m >= 10.0 {
                Visibility::Visible
            } else if peak >= 2.0 {
                Visibility::Marginal
            } else {
                Visibility::Hidden
            }
        })
        .collect()
}

/// A chain of `n` bodies whose anti-resonances and resonances lie in `[lo, hi]` Hz.
pub fn random_chain(rng: &mut impl Rng, n: usize, lo: f64, hi: f64) -> Option<Chain> {
    let j1 = 10f64.powf(rng.random_range(-4.0..-2.0));
    for _ in 0..5000 {
        let inertia: Vec<f64> = (0..n)
            .map(|i| {
                if i == 0 {
                    j1
                } else {
                    j1 * 10f64.powf(rng.random_range(-0.5..1.0))
                }
            })
            .collect();
        // each coupling's two-body frequency log-uniform in the band
        let stiffness: Vec<f64> = (0..n - 1)
            .map(|i| {
                let f = (rng.random_range(lo.ln()..hi.ln())).exp();
                let jr = 1.0 / (1.0 / inertia[i] + 1.0 / inertia[i + 1]);
                jr * (2.0 * std::f64::consts::PI * f).powi(2)
            })
            .collect();
        let zeta: Vec<f64> = (0..n - 1).map(|_| rng.random_range(0.005..0.05)).collect();
        let damping: Vec<f64> = (0..n - 1)
            .map(|i| {
                let jr = 1.0 / (1.0 / inertia[i] + 1.0 / inertia[i + 1]);
                2.0 * zeta[i] * (stiffness[i] * jr).sqrt()
            })
            .collect();
        let Ok(c) = Chain::new(inertia, stiffness, damping) else {
            continue;
        };
        let (ar, r) = (c.antiresonances_hz(), c.resonances_hz());
        let inside = ar.iter().chain(&r).all(|f| *f >= lo && *f <= hi);
        // features at least 10 % and 4 lines (2 Hz at the 0.5 Hz lines) apart: closer
        // than that no measurement at this resolution tells them apart (a technician
        // would lengthen the period)
        let mut all: Vec<f64> = ar.iter().chain(&r).copied().collect();
        all.sort_by(f64::total_cmp);
        let apart = all
            .windows(2)
            .all(|w| w[1] / w[0] > 1.1 && w[1] - w[0] >= 2.0);
        if inside && apart && ar.len() == n - 1 {
            return Some(c);
        }
    }
    None
}

pub fn generate(seed: u64) -> Option<Case> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x1d_e7_1f_7e);
    let n = rng.random_range(2..=5usize);
    let fs: f64 = [1000.0, 2000.0, 4000.0, 8000.0][rng.random_range(0..4usize)];
    let periodic = rng.random_bool(0.5);
    let period = (fs / 0.5).round() as usize; // 0.5 Hz lines
    let (lo, hi) = (4.0, 0.2 * fs);
    let chain = random_chain(&mut rng, n, lo, hi)?;
    let rms = 0.3 * chain.total_inertia().sqrt() / 0.1; // scales with the axis
    let (torque, info): (Vec<f64>, Option<ExcitationInfo>) = if periodic {
        let mut d = MultisineDesign::new(fs, period, [0.5, 0.4 * fs], 10.0 * rms, rms);
        d.phases = PhaseDesign::Random {
            seed: seed.wrapping_mul(7919),
        };
        d.amplitude = AmplitudeShape::Flat;
        d.crest_iterations = 5;
        let m = d.generate().ok()?;
        (m.repeat(9), Some(m.info(8, 1)))
    } else {
        let w = Normal::new(0.0, rms).ok()?;
        let len = 18 * period;
        ((0..len).map(|_| w.sample(&mut rng)).collect(), None)
    };
    let bits = rng.random_range(14..=18u32);
    let noise = rms * 10f64.powf(rng.random_range(-3.0..-1.5));
    let spec = PlantSpec {
        chain: chain.clone(),
        effects: Effects {
            torque_noise_nm: noise,
            encoder_counts_per_rev: Some(1 << bits),
            ..Effects::default()
        },
    };
    let mut sim = PlantSim::new(&spec, fs, 8, seed).ok()?;
    let drift = rng.random_range(-0.5..0.5);
    sim.set_initial_velocity(drift);
    let pos: Vec<f64> = run(&mut sim, &torque).map(|s| s.position_rad).collect();
    // multisine: the power r^2 over L = 0.8 fs lines 0.5 Hz apart, 8 periods of 2 s
    // averaged: SNR^2 = |H|^2 r^2 T fs / (2 L v) = 10 |H|^2 r^2 / v; white noise: 36 s at
    // 0.5 Hz resolution, SNR^2 = 18 |H|^2 r^2 / v
    let gain2 = if periodic { 10.0 } else { 18.0 };
    let q = 2.0 * std::f64::consts::PI / (1u64 << bits) as f64;
    let visibility = visibility(&chain, gain2, rms, q, noise);
    let describe = format!(
        "{n} bodies, {} at {fs} Hz, {bits}-bit encoder, noise {:.1e} of the RMS, drift {drift:+.2} rad/s",
        if periodic { "multisine" } else { "white noise" },
        noise / rms
    );
    let rec = position_recording(fs, torque, pos, info);
    Some(Case {
        rec,
        chain,
        describe,
        visibility,
        noise_model: (gain2, rms, q, noise),
    })
}

/// The model's pairs against the true ones: `(pairs right, order right)`. Pairs are right
/// when every visible true pair has a model pair with both frequencies within 2 % and
/// every model pair is such a match of a visible true pair or has the resonance of a
/// marginal one within 2 % (none where the data carry no information). The order is right when the number of model pairs is
/// between the visible true pairs and the visible and marginal ones.
pub fn score(model: (&[f64], &[f64]), truth: (&[f64], &[f64]), vis: &[Visibility]) -> (bool, bool) {
    let near = |a: f64, b: f64| (a / b - 1.0).abs() <= 0.02;
    let matches = |m: usize, t: usize| near(model.0[m], truth.0[t]) && near(model.1[m], truth.1[t]);
    let n_model = model.0.len().min(model.1.len());
    let visible = vis.iter().filter(|v| **v == Visibility::Visible).count();
    let marginal = vis.iter().filter(|v| **v == Visibility::Marginal).count();
    let found_visible = (0..vis.len())
        .filter(|&t| vis[t] == Visibility::Visible)
        .all(|t| (0..n_model).any(|m| matches(m, t)));
    let no_extra = (0..n_model).all(|m| {
        (0..vis.len()).any(|t| match vis[t] {
            Visibility::Visible => matches(m, t),
            Visibility::Marginal => near(model.1[m], truth.1[t]),
            Visibility::Hidden => false,
        })
    });
    let order = n_model >= visible && n_model <= visible + marginal;
    (found_visible && no_extra, order)
}

/// Whether every true frequency has an estimate within 2 % and the counts agree.
pub fn frequencies_right(est: &[f64], truth: &[f64]) -> bool {
    est.len() == truth.len()
        && truth
            .iter()
            .all(|t| est.iter().any(|e| (e / t - 1.0).abs() <= 0.02))
}

/// Numbers that should never be printed: NaN, infinities (as words of their own, not
/// inside "information"), a relative uncertainty above 100 % (`... 1.2e3 %`). `json` is
/// checked for the same words (serde writes non-finite numbers as `null`, which is the
/// honest form).
pub fn bad_numbers(text: &str, json: &str) -> usize {
    let words = |t: &str| -> Vec<String> {
        t.split(|c: char| c.is_whitespace() || ",;:()[]{}\"=".contains(c))
            .filter(|w| !w.is_empty())
            .map(str::to_lowercase)
            .collect()
    };
    let mut bad = 0;
    for t in [text, json] {
        bad += words(t)
            .iter()
            .filter(|w| matches!(w.trim_start_matches(['+', '-']), "nan" | "inf" | "infinity"))
            .count();
    }
    // relative uncertainties: the tables, not the notes (a note's percentage is a
    // difference between two estimates)
    let tables: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("- "))
        .collect::<Vec<_>>()
        .join("\n");
    let w = words(&tables);
    for pair in w.windows(2) {
        if pair[1] == "%" {
            if let Ok(v) = pair[0].parse::<f64>() {
                if v > 100.0 {
                    bad += 1;
                }
            }
        }
    }
    bad
}

/// Every output a user sees of `a` (the text report, the JSON document, the Bode plot's
/// SVG), checked for numbers that must never be printed: NaN, infinities, a relative
/// uncertainty above 100 % in the text's tables, a JSON model entry whose uncertainty
/// exceeds its value. Returns a line per offence, naming where it is.
pub fn bad_outputs(a: &Analysis) -> Vec<String> {
    let mut bad = Vec::new();
    let text = render_report(a, "case");
    let json = to_json(a);
    let json_text = serde_json::to_string(&json).unwrap_or_default();
    for line in text.lines().filter(|l| bad_numbers(l, "") > 0) {
        bad.push(format!("text: {line}"));
    }
    if bad_numbers("", &json_text) > 0 {
        bad.push("json: NaN or infinity".into());
    }
    let model = &json["model"];
    for (v, s) in [
        ("inertia_kgm2", "inertia_std_kgm2"),
        ("stiffness_nm_per_rad", "stiffness_std_nm_per_rad"),
        ("damping_nms_per_rad", "damping_std_nms_per_rad"),
        ("resonance_hz", "resonance_std_hz"),
        ("antiresonance_hz", "antiresonance_std_hz"),
    ] {
        let (vals, stds) = (&model[v], &model[s]);
        for i in 0..vals.as_array().map_or(0, |x| x.len()) {
            if let (Some(x), Some(sd)) = (vals[i].as_f64(), stds[i].as_f64()) {
                if sd > x.abs() {
                    bad.push(format!("json: {v}[{i}] = {x} +- {sd}"));
                }
            }
        }
    }
    let mut plot = BodePlot::new(&a.measured.frf).title("case");
    if let Some(m) = &a.model_frf {
        plot = plot.model(m, "identified chain");
    }
    if let Some(b) = a.supported_band_hz {
        plot = plot.band_used(b);
    }
    if let Some(m) = &a.model {
        plot = plot
            .anti_resonances(&m.antiresonance_hz)
            .resonances(&m.resonance_hz);
    }
    match plot.render_svg() {
        Ok(svg) => {
            if bad_numbers("", &svg) > 0 {
                bad.push("svg: NaN or infinity".into());
            }
        }
        Err(e) => bad.push(format!("svg: not drawn: {e}")),
    }
    bad
}

/// A recording of torque command and motor position at `fs` [Hz], with the excitation's
/// description when it is periodic.
pub fn position_recording(
    fs: f64,
    torque: Vec<f64>,
    pos: Vec<f64>,
    info: Option<ExcitationInfo>,
) -> Recording {
    Recording::of_position(fs, torque, pos, info)
}

//! `gravity`: a restoring stiffness from the load to the ground (at small angles
//! `m g l`), so that the low-frequency end no longer behaves like a free inertia; with the
//! damping of the swinging mode it creates (a damper from the load to the ground, where a
//! swinging link's bearing is: without one the mode never settles; the motor's viscous
//! friction stays the nominal model's).

use super::{finish_linear, fit_best_start, log_std, EffectFit, Lin, Param};
use crate::diagnose::lti::LinExt;
use crate::diagnose::Data;
use crate::diagnose::Effect;
use crate::frf::Frf;
use crate::identify::detect::{detect_pairs, normalized_response, DetectOptions, Detection};
use crate::identify::exact::{chain_from_spectra, with_coupling_damping};
use crate::model::Chain;

/// Identify gravity with the chain, started from `nominal` (and from the chains `idents`
/// with its extensions: a nominal chain fitted without gravity can have bent a nearly
/// free body into mimicking it, whose spring is then softer than any restoring stiffness
/// the data need) plus a grid of restoring stiffnesses and dampings.
///
/// Two more families of starts, each refined on its own (their first cost is no guide:
/// the grid's starts begin next to the nominal model's chi², these far from it, and they
/// end far below it): where the nominal chain took the ground as its last body, the bodies
/// before it given their missing body back at the frequencies `gap_hz` where the nominal
/// model's gap is largest or at a resonance the detection saw ([`body_split_off`]); and
/// the grounded chain read off the measured spectra ([`Detected::grounded`]).
pub fn fit(data: &Data, nominal: &LinExt, idents: &[Chain], gap_hz: &[f64]) -> Option<EffectFit> {
    let w0 = 2.0 * std::f64::consts::PI * data.f_min();
    // a chain whose last body is the ground (far heavier than the rest: the nominal fit
    // took gravity as a body) is no base for a restoring stiffness on top as it is; with
    // its last body made a body again (the size of the others, half and twice), it is
    let bases: Vec<LinExt> = std::iter::once(nominal.clone())
        .chain(idents.iter().map(|c| LinExt {
            chain: c.clone(),
            ..nominal.clone()
        }))
        .flat_map(|b| {
            if ends_in_ground(&b.chain) {
                unpinned(&b)
            } else {
                vec![b]
            }
        })
        .collect();
    let mut starts: Vec<LinExt> = bases
        .iter()
        .flat_map(|base| {
            let jt = base.chain.total_inertia();
            [0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0]
                .iter()
                .flat_map(|m| [0.02, 0.1, 0.3].map(|z| (*m, z)))
                .map(move |(m, z)| {
                    let mut s = base.clone();
                    s.ground_k = m * jt * w0 * w0;
                    s.ground_b = 2.0 * z * (s.ground_k * jt).sqrt();
                    s
                })
        })
        .collect();
    if ends_in_ground(&nominal.chain) {
        starts.extend(held_like_the_ground(nominal));
    }
    let seen = Detected::of(data);
    let split = if ends_in_ground(&nominal.chain) {
        let mut at_hz = gap_hz.to_vec();
        at_hz.extend(seen.iter().flat_map(Detected::resonances_hz));
        body_split_off(nominal, &at_hz)
    } else {
        Vec::new()
    };
    let read: Vec<LinExt> = seen.and_then(|d| d.grounded(nominal)).into_iter().collect();
    let (m, r) = [
        fit_best_start(data, Lin::Gravity, &starts, 80, 3),
        fit_best_start(data, Lin::Gravity, &split, 80, 1),
        fit_best_start(data, Lin::Gravity, &read, 80, 1),
    ]
    .into_iter()
    .flatten()
    .min_by(|a, b| a.1.cost.total_cmp(&b.1.cost))?;
    Some(finish(data, m, &r))
}

/// Starts from a nominal chain whose last body is the ground ([`ends_in_ground`]): such a
/// fit has one real body too few (the ground took its place, two bodies merged), so one of
/// the bodies before the ground is split in two (a fifth, a half, four fifths of it on the
/// motor side) joined by the coupling whose two-body resonance is at a frequency of
/// `at_hz` (where the nominal model's gap is, and the resonances the detection saw); the
/// ground's spring becomes the restoring stiffness with a tenth of critical damping, the
/// new coupling 3 % of its critical damping. Empty when the chain does not end in the
/// ground.
fn body_split_off(nominal: &LinExt, at_hz: &[f64]) -> Vec<LinExt> {
    let Some((bodies, k)) = without_ground_body(&nominal.chain) else {
        return Vec::new();
    };
    let mut freqs: Vec<f64> = Vec::new();
    for &f in at_hz {
        if f > 0.0
            && !freqs
                .iter()
                .any(|&g| (f / g).ln().abs() < super::START_FREQ_RATIO.ln())
        {
            freqs.push(f);
        }
    }
    let mut out = Vec::new();
    for i in 0..bodies.masses() {
        for rho in [0.2, 0.5, 0.8] {
            for &f in &freqs {
                let ji = bodies.inertia_kgm2[i];
                let (ja, jb) = (rho * ji, (1.0 - rho) * ji);
                let c = ja * jb / ji * (2.0 * std::f64::consts::PI * f).powi(2);
                let mut j = bodies.inertia_kgm2.clone();
                let mut cs = bodies.stiffness_nm_per_rad.clone();
                let mut ds = bodies.damping_nms_per_rad.clone();
                j[i] = ja;
                j.insert(i + 1, jb);
                cs.insert(i, c);
                ds.insert(i, 2.0 * 0.03 * (c * ja * jb / ji).sqrt());
                let Ok(chain) = Chain::new(j, cs, ds) else {
                    continue;
                };
                let jt = chain.total_inertia();
                out.push(LinExt {
                    chain,
                    ground_k: k,
                    ground_b: 0.2 * (k * jt).sqrt(),
                    ..nominal.clone()
                });
            }
        }
    }
    out
}

/// The measured response of the level with the highest torque, its whole samples of
/// delay, and its anti-resonance/resonance detection: what the gravity starts read off
/// the spectra.
pub struct Detected {
    frf: Frf,
    io_delay: u32,
    det: Detection,
}

impl Detected {
    /// The detection on the level with the highest torque; `None` where it fails (too few
    /// lines).
    pub fn of(data: &Data) -> Option<Self> {
        let l = &data.levels[crate::diagnose::top_level(data)];
        let frf = Frf {
            freq_hz: l.f.clone(),
            h: l.h.clone(),
            var: l.var.clone(),
            coherence: None,
            kind: data.kind,
            sample_rate_hz: data.fs,
        };
        let det = detect_pairs(
            &frf,
            &DetectOptions {
                delay_samples: l.io_delay,
                ..DetectOptions::default()
            },
        )
        .ok()?;
        Some(Detected {
            frf,
            io_delay: l.io_delay,
            det,
        })
    }

    /// The resonances [Hz] the detection saw: its peaks and the resonances of its pairs,
    /// confirmed or not.
    pub fn resonances_hz(&self) -> Vec<f64> {
        let det = &self.det;
        det.peaks
            .iter()
            .map(|p| p.freq_hz)
            .chain(det.pairs.iter().chain(&det.unconfirmed).map(|p| p.r_hz))
            .collect()
    }

    /// The grounded chain read off the measured spectra, with `base`'s other extensions and
    /// as many bodies as its chain: the paper's identification from the spectra
    /// ([`chain_from_spectra`]) for a chain held to the ground at its load. A restoring
    /// stiffness `k_g` on the last body makes the motor's response one resonance richer
    /// than its anti-resonances,
    ///
    /// ```text
    /// X(s) = (1/k_g) prod_(i<n) (1 + s²/w_AR,i²) / prod_(i<=n) (1 + s²/w_R,i²)
    /// ```
    ///
    /// (the lowest resonance, the load swinging on `k_g`, has no anti-resonance below it:
    /// the detection reports it `ar_below_band`). That is a free chain of `n + 1` bodies
    /// whose last body is the ground: its lowest anti-resonance `w_AR,0 = sqrt(k_g / J_t)`
    /// goes to zero as the ground's inertia grows. So the chain comes from the free chain's
    /// inverse with a ground body of `10^4` times the rest (`w_AR,0 = w_R,1 / 100`), the
    /// ground split off ([`without_ground_body`]); `k_g` from the median over the lines of
    /// `w² |X_shape(w)| / |R(w)|` (`R = -w² X`, the normalised response), and 3 % of
    /// critical damping per coupling and a tenth of critical to the ground. `None` unless
    /// exactly `n` pairs are detected (the unconfirmed ones counted where the confirmed are
    /// too few), the lowest one with its anti-resonance below the band, and the spectra
    /// interlace.
    pub fn grounded(&self, base: &LinExt) -> Option<LinExt> {
        let (frf, io_delay, det) = (&self.frf, self.io_delay, &self.det);
        let n = base.chain.masses();
        // the confirmed pairs, or with the unconfirmed ones (below the detection's
        // thresholds, offered to the order selection) where that makes the `n` a chain of
        // `n` bodies has
        let mut pairs = det.pairs.clone();
        if pairs.len() < n {
            pairs.extend(det.unconfirmed.iter().cloned());
            pairs.sort_by(|a, b| a.r_hz.total_cmp(&b.r_hz));
        }
        if pairs.len() != n || !pairs[0].ar_below_band {
            return None;
        }
        let r: Vec<f64> = pairs.iter().map(|p| p.r_hz).collect();
        let ar: Vec<f64> = pairs[1..].iter().map(|p| p.ar_hz).collect();
        // k_g: the undamped shape against the measured inverse effective inertia
        let nr = normalized_response(frf, None, io_delay).ok()?;
        let mut kg: Vec<f64> = nr
            .freq_hz
            .iter()
            .zip(&nr.r)
            .filter_map(|(&f, rr)| {
                let shape = ar
                    .iter()
                    .map(|a| (1.0 - (f / a).powi(2)).abs())
                    .product::<f64>()
                    / r.iter()
                        .map(|q| (1.0 - (f / q).powi(2)).abs())
                        .product::<f64>();
                let w = 2.0 * std::f64::consts::PI * f;
                let k = w * w * shape / rr.norm();
                (k.is_finite() && k > 0.0).then_some(k)
            })
            .collect();
        if kg.is_empty() {
            return None;
        }
        kg.sort_by(f64::total_cmp);
        let kg = kg[kg.len() / 2];
        let w1 = 2.0 * std::f64::consts::PI * r[0];
        let j_ground = 1e4 * kg / (w1 * w1);
        let ar0: Vec<f64> = std::iter::once(r[0] / 100.0).chain(ar).collect();
        let free = chain_from_spectra(j_ground, &ar0, &r).ok()?;
        let (bodies, k) = without_ground_body(&with_coupling_damping(free, 0.03))?;
        let jt = bodies.total_inertia();
        Some(LinExt {
            chain: bodies,
            ground_k: k,
            ground_b: 0.2 * (k * jt).sqrt(),
            ..base.clone()
        })
    }
}

/// `base` whose last body (the ground, [`ends_in_ground`]) is made an ordinary body: the
/// mean of the others, half and twice it, its spring kept (the restoring stiffness on top
/// then holds it to the ground, as the ground body did).
fn unpinned(base: &LinExt) -> Vec<LinExt> {
    let n = base.chain.masses();
    let mean = base.chain.inertia_kgm2[..n - 1].iter().sum::<f64>() / (n - 1) as f64;
    [0.5, 1.0, 2.0]
        .iter()
        .filter_map(|f| {
            let mut j = base.chain.inertia_kgm2.clone();
            j[n - 1] = f * mean;
            let chain = Chain::new(
                j,
                base.chain.stiffness_nm_per_rad.clone(),
                base.chain.damping_nms_per_rad.clone(),
            )
            .ok()?;
            Some(LinExt {
                chain,
                ..base.clone()
            })
        })
        .collect()
}

/// Starts on the scale of the spring that held a ground body ([`ends_in_ground`]): the
/// last body made a body again ([`unpinned`]) with a restoring stiffness of 0.3, 1 and 3
/// times that spring (the ground body's spring carried the coupling and gravity in
/// series) and a tenth of critical damping.
fn held_like_the_ground(base: &LinExt) -> Vec<LinExt> {
    let k_last = base
        .chain
        .stiffness_nm_per_rad
        .last()
        .copied()
        .unwrap_or(0.0);
    unpinned(base)
        .into_iter()
        .flat_map(|b| {
            [0.3, 1.0, 3.0].map(|f| {
                let mut s = b.clone();
                s.ground_k = f * k_last;
                s.ground_b = 0.2 * (s.ground_k * s.chain.total_inertia()).sqrt();
                s
            })
        })
        .collect()
}

/// Whether the last body of `chain` is far heavier (20x) than all the others together:
/// the ground, its spring a restoring stiffness.
pub fn ends_in_ground(chain: &Chain) -> bool {
    let n = chain.masses();
    n >= 2 && {
        let je = chain.inertia_kgm2[n - 1];
        let rest: f64 = chain.inertia_kgm2[..n - 1].iter().sum();
        je > 20.0 * rest
    }
}

/// Gravity started from a chain whose last body is the ground ([`ends_in_ground`]: an
/// extra-body fit, or a nominal fit, that found it): the bodies before it, its spring as
/// the restoring stiffness. None when the last body is not such a ground.
pub fn from_ground_body(data: &Data, chain: &Chain) -> Option<EffectFit> {
    let (body, k) = without_ground_body(chain)?;
    let rest = body.total_inertia();
    let starts: Vec<LinExt> = [0.02, 0.1, 0.3]
        .iter()
        .map(|z| {
            let mut s = LinExt::nominal(body.clone());
            s.ground_k = k;
            s.ground_b = 2.0 * z * (k * rest).sqrt();
            s
        })
        .collect();
    let (m, r) = fit_best_start(data, Lin::Gravity, &starts, 80, 1)?;
    Some(finish(data, m, &r))
}

/// A chain whose last body is the ground ([`ends_in_ground`]) as the bodies before it and
/// the stiffness [N m/rad] of the spring that ties them to the ground; `None` when the last
/// body is not such a ground.
pub fn without_ground_body(chain: &Chain) -> Option<(Chain, f64)> {
    if !ends_in_ground(chain) {
        return None;
    }
    let n = chain.masses();
    let body = Chain::new(
        chain.inertia_kgm2[..n - 1].to_vec(),
        chain.stiffness_nm_per_rad[..n - 2].to_vec(),
        chain.damping_nms_per_rad[..n - 2].to_vec(),
    )
    .ok()?;
    Some((body, chain.stiffness_nm_per_rad[n - 2]))
}

/// An extra-body fit whose new body is the ground ([`ends_in_ground`]) *is* a restoring
/// stiffness: within the band a body that heavy does not move, and its spring acts from
/// the load to the ground. The same fit (model and chi²), named gravity, its spring as
/// `m g l` and its damper as the load-ground damping (the heavy inertia is no parameter
/// the data can fix: two are added, as for gravity). `None` when the last body is not
/// such a ground.
pub fn from_ground_mode(mode: &EffectFit) -> Option<EffectFit> {
    let ch = &mode.lin.chain;
    if !ends_in_ground(ch) {
        return None;
    }
    let k = *ch.stiffness_nm_per_rad.last()?;
    let c = *ch.damping_nms_per_rad.last()?;
    Some(EffectFit {
        effect: Effect::Gravity,
        params: vec![
            Param {
                name: "m_g_l_nm".into(),
                value: k,
                std: f64::NAN,
            },
            Param {
                name: "damping_load_ground_nms_per_rad".into(),
                value: c,
                std: f64::NAN,
            },
        ],
        added: 2,
        ..mode.clone()
    })
}

fn finish(data: &Data, m: LinExt, r: &crate::lsq::LmResult) -> EffectFit {
    let i0 = super::nominal_params(&m, Lin::Gravity);
    let p = vec![
        Param {
            name: "m_g_l_nm".into(),
            value: m.ground_k,
            std: log_std(r, i0, m.ground_k),
        },
        Param {
            name: "damping_load_ground_nms_per_rad".into(),
            value: m.ground_b,
            std: log_std(r, i0 + 1, m.ground_b),
        },
    ];
    finish_linear(data, Effect::Gravity, m, p, 2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::tests_support::exact_data;

    /// An extra-body fit whose body is 1e4 times the chain is gravity (same chi², its
    /// spring as `m g l`); a light extra body stays a mode.
    #[test]
    fn a_mode_whose_body_is_the_ground_is_gravity() {
        let chain = |je: f64| {
            Chain::new(vec![2e-3, 5e-3, je], vec![300.0, 2.5], vec![0.02, 0.004]).unwrap()
        };
        let heavy = LinExt::nominal(chain(70.0));
        let (data, _) = exact_data(&heavy, 2000.0, &[2.0, 400.0], 60);
        let mode = finish_linear(&data, Effect::UnmodelledMode, heavy, vec![], 3);
        let g = from_ground_mode(&mode).expect("the ground");
        assert_eq!(g.effect, Effect::Gravity);
        assert_eq!(g.added, 2);
        assert_eq!(g.chi2, mode.chi2);
        assert_eq!(g.params[0].name, "m_g_l_nm");
        assert_eq!(g.params[0].value, 2.5);
        let light = finish_linear(
            &data,
            Effect::UnmodelledMode,
            LinExt::nominal(chain(1e-3)),
            vec![],
            3,
        );
        assert!(from_ground_mode(&light).is_none());
    }

    /// A nominal chain that took the ground as its last body (the plant's last body held
    /// by a strong gravity) is still a base for gravity: its last body made a body again.
    /// Before, every base was dropped and gravity had "no fit" (world seed 50803).
    #[test]
    fn gravity_is_fitted_from_a_nominal_chain_ending_in_the_ground() {
        let bodies = |je: f64| {
            Chain::new(vec![2e-3, 5e-3, je], vec![300.0, 2.5], vec![0.02, 0.004]).unwrap()
        };
        let truth = LinExt {
            ground_k: 3.0,
            ground_b: 0.01,
            ..LinExt::nominal(bodies(4e-3))
        };
        let (data, _) = exact_data(&truth, 2000.0, &[1.0, 400.0], 80);
        let pinned = LinExt::nominal(bodies(70.0));
        assert!(ends_in_ground(&pinned.chain));
        let g = fit(&data, &pinned, &[], &[]).expect("a gravity fit");
        assert_eq!(g.effect, Effect::Gravity);
        // what the diagnosis needs: gravity explains what the pinned chain leaves, by the
        // diagnosis's own rule (more than half of it; here 98.7 %: the fit ends next to
        // the truth, m g l 2.49 for 3.0, the spring and the ground sharing the load)
        let pinned_chi2 = data.chi2_of(&pinned);
        assert!(
            g.chi2 < 0.5 * pinned_chi2,
            "chi2 {} vs pinned {pinned_chi2}",
            g.chi2
        );
        assert!(g.params[0].value > 0.5 * 3.0, "m g l {}", g.params[0].value);
    }

    /// The grounded chain is read off an exact response of a 3-body chain whose load swings
    /// on a restoring stiffness (reference: the parameters it was made from; the spectra
    /// are read by the detection from the lines, so to a few per cent).
    #[test]
    fn a_grounded_chain_is_read_off_its_spectra() {
        let truth = LinExt {
            ground_k: 3.0,
            ground_b: 0.004,
            ..LinExt::nominal(
                Chain::new(vec![2e-3, 5e-3, 4e-3], vec![300.0, 20.0], vec![0.02, 0.004]).unwrap(),
            )
        };
        let (data, _) = exact_data(&truth, 2000.0, &[1.0, 400.0], 400);
        let base = LinExt::nominal(truth.chain.clone());
        let got = Detected::of(&data)
            .and_then(|d| d.grounded(&base))
            .expect("a grounded chain");
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(rel(got.ground_k, 3.0) < 0.05, "k_g {}", got.ground_k);
        for i in 0..3 {
            let (a, b) = (got.chain.inertia_kgm2[i], truth.chain.inertia_kgm2[i]);
            assert!(rel(a, b) < 0.05, "J{i} {a} for {b}");
        }
        for i in 0..2 {
            let (a, b) = (
                got.chain.stiffness_nm_per_rad[i],
                truth.chain.stiffness_nm_per_rad[i],
            );
            assert!(rel(a, b) < 0.05, "c{i} {a} for {b}");
        }
        // a free chain has no such reading: its lowest pair has its anti-resonance in the band
        let free = LinExt::nominal(truth.chain.clone());
        let (data, _) = exact_data(&free, 2000.0, &[1.0, 400.0], 400);
        assert!(Detected::of(&data)
            .and_then(|d| d.grounded(&base))
            .is_none());
    }

    /// A nominal chain that took the ground as its last body and merged two real bodies
    /// (the motor and a body behind a stiff coupling, whose pair is far above the others):
    /// gravity is fitted on the chain with its missing body split off again at the
    /// resonance the detection sees (reference: the parameters the exact response was made
    /// from; world seed 50803, where gravity fitted on the merged chain left chi² 100
    /// times the truth's and a ground cubic took the name).
    #[test]
    fn gravity_is_fitted_where_the_nominal_chain_merged_two_bodies() {
        let truth = LinExt {
            ground_k: 2.7,
            ground_b: 0.044,
            ..LinExt::nominal(
                Chain::new(
                    vec![1.9e-3, 0.9e-3, 0.63e-3, 2.7e-3],
                    vec![13000.0, 120.0, 5.0],
                    vec![0.22, 0.017, 0.0013],
                )
                .unwrap(),
            )
        };
        let (data, _) = exact_data(&truth, 4000.0, &[1.0, 1600.0], 300);
        // the merged chain, as a nominal fit without gravity gives it: motor and second
        // body as one, the ground as a body on gravity's spring
        let merged = LinExt::nominal(
            Chain::new(
                vec![2.8e-3, 0.63e-3, 2.7e-3, 1e3],
                vec![120.0, 5.0, 2.7],
                vec![0.017, 0.0013, 0.04],
            )
            .unwrap(),
        );
        assert!(ends_in_ground(&merged.chain));
        let g = fit(&data, &merged, &[], &[]).expect("a gravity fit");
        let mgl = g.params[0].value;
        assert!((mgl / 2.7 - 1.0).abs() < 0.02, "m g l {mgl}");
        let c0 = g.lin.chain.stiffness_nm_per_rad[0];
        assert!((c0 / 13000.0 - 1.0).abs() < 0.05, "motor coupling {c0}");
        // the fit ends at the truth: chi² of noise-free data far below one per line
        assert!(g.chi2 < 1e-2 * data.lines() as f64, "chi2 {}", g.chi2);
        // the split-off starts on their own (exact data let the detection read all four
        // pairs, so the spectra's start alone also gets there): each body split in two at
        // the frequency given, the inertia kept, the ground's spring on top
        let f = 745.0;
        let split = body_split_off(&merged, &[f]);
        assert_eq!(split.len(), 3 * 3);
        for s in &split {
            assert_eq!(s.chain.masses(), 4);
            assert!((s.chain.total_inertia() / 6.13e-3 - 1.0).abs() < 1e-12);
            assert_eq!(s.ground_k, 2.7);
            // one coupling of the split resonates alone at f
            let c = &s.chain;
            let at_f = (0..3).any(|i| {
                let (ja, jb) = (c.inertia_kgm2[i], c.inertia_kgm2[i + 1]);
                let w = (c.stiffness_nm_per_rad[i] * (1.0 / ja + 1.0 / jb)).sqrt();
                (w / (2.0 * std::f64::consts::PI * f) - 1.0).abs() < 1e-9
            });
            assert!(at_f, "{c:?}");
        }
        let g = fit_best_start(&data, Lin::Gravity, &split, 80, 1)
            .expect("a fit")
            .0;
        assert!(
            (g.ground_k / 2.7 - 1.0).abs() < 0.02,
            "m g l {}",
            g.ground_k
        );
    }
}

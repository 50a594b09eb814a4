//! The parameter search of an amplitude-dependent effect: simulate the chain + effect on
//! every recorded excitation, estimate the FRFs like the measurement's, and minimise the
//! chi² over one scale parameter (log grid, then golden section), correcting the chain in
//! between (a joint linear refit on the measurement with the simulated effect divided out).

use super::effects::{fit_linear, EffectFit, Lin, Param, Target};
use super::lti::{Discrete, LinExt};
use super::nlsim::{sim_frf, simulate, Nl};
use super::Data;
use num_complex::Complex64;

/// Model FRFs of `lin` + `nl` on every level (all lines). `short`: simulate only the
/// transient periods and one steady period (the search; the final model uses them all).
pub fn sim_model(data: &Data, lin: &LinExt, nl: Nl, short: bool) -> Option<Vec<Vec<Complex64>>> {
    data.levels
        .iter()
        .map(|l| {
            let u = &l.rec.torque_cmd_nm;
            let n = match (&l.rec.sidecar.excitation, short) {
                (Some(e), true) if e.period_samples > 0 => {
                    ((e.transient_periods + 1) * e.period_samples).min(u.len())
                }
                _ => u.len(),
            };
            // the spring nonlinearities act at the gear's frequency: finer sub-steps
            let sub = match nl {
                Nl::Backlash { .. } | Nl::Hardening { .. } => data.spring_substeps,
                _ => data.substeps,
            };
            let out = simulate(lin, nl, &u[..n], data.fs, sub);
            sim_frf(&l.rec, data.band, &l.keep, &out)
        })
        .collect()
}

fn chi2_of(data: &Data, lin: &LinExt, nl: Nl) -> f64 {
    sim_model(data, lin, nl, true)
        .map(|m| data.chi2(&m))
        .unwrap_or(f64::INFINITY)
}

/// Minimise chi²(p) over `p` in `[lo, hi]` (log scale): `grid` points then `golden` steps.
/// Returns (p, chi², sigma of ln p from the curvature).
fn search_1d(
    lo: f64,
    hi: f64,
    grid: usize,
    golden: usize,
    curvature: bool,
    mut f: impl FnMut(f64) -> f64,
) -> (f64, f64, f64) {
    let (la, lb) = (lo.ln(), hi.ln());
    let pts: Vec<f64> = (0..grid)
        .map(|i| la + (lb - la) * i as f64 / (grid - 1).max(1) as f64)
        .collect();
    let vals: Vec<f64> = pts.iter().map(|&l| f(l.exp())).collect();
    let ib = (0..grid)
        .min_by(|&a, &b| vals[a].total_cmp(&vals[b]))
        .unwrap();
    let (mut a, mut b) = (pts[ib.saturating_sub(1)], pts[(ib + 1).min(grid - 1)]);
    let mut best = (pts[ib], vals[ib]);
    if golden == 0 {
        return (best.0.exp(), best.1, f64::NAN);
    }
    let gr = 0.618_033_988_75;
    let mut c = b - gr * (b - a);
    let mut d = a + gr * (b - a);
    let (mut fc, mut fd) = (f(c.exp()), f(d.exp()));
    for _ in 0..golden {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - gr * (b - a);
            fc = f(c.exp());
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + gr * (b - a);
            fd = f(d.exp());
        }
    }
    for (x, v) in [(c, fc), (d, fd)] {
        if v < best.1 {
            best = (x, v);
        }
    }
    if !curvature {
        return (best.0.exp(), best.1, f64::NAN);
    }
    // curvature from three points around the optimum
    let h = ((b - a).abs() * 0.5).max(0.02);
    let (fm, fp) = (f((best.0 - h).exp()), f((best.0 + h).exp()));
    let curv = (fp + fm - 2.0 * best.1) / (h * h);
    let sig = if curv > 0.0 {
        (2.0 / curv).sqrt()
    } else {
        f64::NAN
    };
    (best.0.exp(), best.1, sig)
}

/// Identify an amplitude-dependent effect `make(p)` with `p` in `[lo, hi]`; `with_viscous`
/// adds a motor-ground damper to the chain correction (friction).
pub fn fit_nonlinear(
    data: &Data,
    nominal: &LinExt,
    effect: &'static str,
    pname: &str,
    lo: f64,
    hi: f64,
    with_viscous: bool,
    make: impl Fn(f64) -> Nl,
) -> Option<EffectFit> {
    let mut lin = nominal.clone();
    if with_viscous {
        // the viscous part is linear: fitted first on the highest level, where the
        // Coulomb part matters least
        let top = (0..data.levels.len())
            .max_by(|&a, &b| {
                data.levels[a]
                    .torque_rms
                    .total_cmp(&data.levels[b].torque_rms)
            })
            .unwrap();
        let jw = lin.chain.total_inertia() * 2.0 * std::f64::consts::PI * data.f_min().max(1e-3);
        let mut best: Option<(LinExt, f64)> = None;
        for b0 in [0.01 * jw, 0.3 * jw] {
            let mut s = lin.clone();
            s.motor_b = b0;
            if let Some((m, r)) =
                fit_linear(data, &data.targets[top..top + 1], Lin::Viscous, &s, 25)
            {
                if best.as_ref().is_none_or(|b| r.cost < b.1) {
                    best = Some((m, r.cost));
                }
            }
        }
        if let Some((m, _)) = best {
            lin = m;
        }
    }
    let (mut p, _, mut sig) = search_1d(lo, hi, 6, 4, false, |p| chi2_of(data, &lin, make(p)));
    // alternate: correct the chain (the measurement with the simulated effect divided
    // out), then search again around the current value
    for round in 0..2 {
        let model = sim_model(data, &lin, make(p), true)?;
        lin = correct_chain(data, &lin, &model, with_viscous);
        let (w, grid) = if round == 0 { (3.0, 4) } else { (1.6, 3) };
        let r = search_1d(p / w, p * w, grid, 3, round == 1, |q| {
            chi2_of(data, &lin, make(q))
        });
        p = r.0;
        sig = r.2;
    }
    finish(data, lin, make(p), effect, pname, p, sig, with_viscous)
}

/// The chain corrected for a simulated effect: refitted to the measurement with the
/// effect divided out (`H_meas H_lin / H_sim`, `model` = `H_sim` on all lines).
fn correct_chain(
    data: &Data,
    lin: &LinExt,
    model: &[Vec<Complex64>],
    with_viscous: bool,
) -> LinExt {
    let targets: Vec<Target> = data
        .levels
        .iter()
        .zip(&data.targets)
        .zip(model)
        .map(|((l, t), ms)| {
            let d = Discrete::new(lin, data.fs, l.io_delay);
            let h = t
                .idx
                .iter()
                .zip(&t.h)
                .map(|(&i, &h)| h * d.frf(l.f[i], data.kind) / ms[i])
                .collect();
            Target { h, ..t.clone() }
        })
        .collect();
    let mut start = lin.clone();
    let k = if with_viscous {
        start.motor_b = start
            .motor_b
            .max(1e-6 * start.chain.total_inertia() * data.f_min());
        Lin::Viscous
    } else {
        Lin::None
    };
    fit_linear(data, &targets, k, &start, 25)
        .map(|r| r.0)
        .unwrap_or_else(|| lin.clone())
}

/// The identified effect: the full-length simulation on all lines, chi², parameters.
#[allow(clippy::too_many_arguments)]
fn finish(
    data: &Data,
    lin: LinExt,
    nl: Nl,
    effect: &'static str,
    pname: &str,
    p: f64,
    sig: f64,
    with_viscous: bool,
) -> Option<EffectFit> {
    let model = sim_model(data, &lin, nl, false)?;
    let chi2 = data.chi2(&model);
    let mut params = vec![Param {
        name: pname.into(),
        value: p,
        std: p * sig,
    }];
    if with_viscous {
        params.push(EffectFit::param(
            "viscous_nms_per_rad",
            lin.motor_b,
            f64::NAN,
        ));
    }
    Some(EffectFit {
        effect,
        params,
        added: 2,
        chi2,
        model,
        lin,
    })
}

/// A nonlinear effect of one coupling (backlash, hardening): [`fit_nonlinear`] on each
/// coupling `k`, its parameter searched in `[lo, hi] x` the coupling's RMS deflection
/// (at the lowest level when `lowest_level`, else the highest); the best fit, with the
/// coupling index added as a parameter.
#[allow(clippy::too_many_arguments)]
pub fn fit_per_coupling(
    data: &Data,
    nominal: &LinExt,
    lowest_level: bool,
    effect: &'static str,
    pname: &str,
    lo: f64,
    hi: f64,
    make: impl Fn(usize, f64) -> Nl,
) -> Option<EffectFit> {
    let mut best: Option<EffectFit> = None;
    for k in 0..nominal.chain.masses().saturating_sub(1) {
        let x = data.deflection_rms(nominal, k, lowest_level);
        if !(x > 0.0) {
            continue;
        }
        let Some(mut e) = fit_nonlinear(data, nominal, effect, pname, lo * x, hi * x, false, |v| {
            make(k, v)
        }) else {
            continue;
        };
        e.params.push(EffectFit::param("coupling", k as f64, 0.0));
        if best.as_ref().is_none_or(|b| e.chi2 < b.chi2) {
            best = Some(e);
        }
    }
    best
}

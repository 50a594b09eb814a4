//! Tests of the FRF matrix estimator: a naive-DFT reference of the fast path, and a coupled
//! multi-axis plant of the test's own (exact ZOH by the matrix exponential) driven by the
//! orthogonal multisines through the time domain, noise-free and with noise (Monte Carlo).

use super::*;
use crate::excitation::{OrthogonalMultisine, OrthogonalMultisineDesign};
use crate::frf::testutil::{dft_line, gauss, rng, Biquad};
use rand::rngs::StdRng;
use std::f64::consts::PI;

type CMat = DMatrix<Complex64>;

/// One experiment's record: the `N` torque channels and the `N` velocity channels.
#[derive(Clone)]
struct Record {
    u: Vec<Vec<f64>>,
    y: Vec<Vec<f64>>,
}

/// The test's reference plant: `N` axes, each a motor inertia with a gear spring-damper to
/// an arm inertia, neighbouring arms coupled by a spring-damper, viscous friction of motors
/// and arms to the ground (so every transient dies out). States `[q_m, q_a, v_m, v_a]`,
/// inputs the motor torques [N m], outputs the motor velocities [rad/s]. Exact zero-order
/// hold: `exp([[A, B], [0, 0]] T) = [[Ad, Bd], [0, I]]`.
struct Plant {
    ad: DMatrix<f64>,
    bd: DMatrix<f64>,
    c: DMatrix<f64>,
}

impl Plant {
    fn chain(axes: usize, fs: f64) -> Self {
        let nb = 2 * axes;
        let ns = 2 * nb;
        let jm = |i: usize| 1.0e-3 * (1.0 + 0.2 * i as f64);
        let ja = |i: usize| 4.0e-3 / (1.0 + 0.3 * i as f64);
        let mut k = DMatrix::<f64>::zeros(nb, nb);
        let mut d = DMatrix::<f64>::zeros(nb, nb);
        let link = |m: &mut DMatrix<f64>, i: usize, j: usize, v: f64| {
            m[(i, i)] += v;
            m[(j, j)] += v;
            m[(i, j)] -= v;
            m[(j, i)] -= v;
        };
        for n in 0..axes {
            link(&mut k, n, axes + n, 40.0 - 8.0 * n as f64);
            link(&mut d, n, axes + n, 0.05);
            d[(n, n)] += 0.1;
            d[(axes + n, axes + n)] += 0.05;
        }
        for n in 0..axes.saturating_sub(1) {
            link(&mut k, axes + n, axes + n + 1, 15.0);
            link(&mut d, axes + n, axes + n + 1, 0.03);
        }
        let inv_m: Vec<f64> = (0..nb)
            .map(|i| 1.0 / if i < axes { jm(i) } else { ja(i - axes) })
            .collect();
        let mut aug = DMatrix::<f64>::zeros(ns + axes, ns + axes);
        for i in 0..nb {
            aug[(i, nb + i)] = 1.0;
            for j in 0..nb {
                aug[(nb + i, j)] = -inv_m[i] * k[(i, j)];
                aug[(nb + i, nb + j)] = -inv_m[i] * d[(i, j)];
            }
        }
        for n in 0..axes {
            aug[(nb + n, ns + n)] = inv_m[n];
        }
        let e = (aug / fs).exp();
        let mut c = DMatrix::<f64>::zeros(axes, ns);
        for n in 0..axes {
            c[(n, nb + n)] = 1.0;
        }
        Plant {
            ad: e.view((0, 0), (ns, ns)).into_owned(),
            bd: e.view((0, ns), (ns, axes)).into_owned(),
            c,
        }
    }

    /// `y[t] = C x[t]`, `x[t+1] = Ad x[t] + Bd u[t]`, from rest.
    fn simulate(&self, u: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let (ns, axes) = (self.ad.nrows(), u.len());
        let len = u[0].len();
        let mut x = vec![0.0; ns];
        let mut next = vec![0.0; ns];
        let mut y = vec![vec![0.0; len]; axes];
        for t in 0..len {
            for (n, yn) in y.iter_mut().enumerate() {
                yn[t] = (0..ns).map(|s| self.c[(n, s)] * x[s]).sum();
            }
            for (i, v) in next.iter_mut().enumerate() {
                *v = (0..ns).map(|s| self.ad[(i, s)] * x[s]).sum::<f64>()
                    + (0..axes).map(|a| self.bd[(i, a)] * u[a][t]).sum::<f64>();
            }
            std::mem::swap(&mut x, &mut next);
        }
        y
    }

    /// Closed loop from rest: the logged torque `u = r - kd y` [N m], `y = C x + noise`
    /// the measured motor velocity [rad/s] (noise-free when `noise` is `None`).
    fn simulate_closed(&self, r: &[Vec<f64>], kd: f64, noise: Option<&[Vec<f64>]>) -> Record {
        let (ns, axes) = (self.ad.nrows(), r.len());
        let len = r[0].len();
        let mut x = vec![0.0; ns];
        let mut next = vec![0.0; ns];
        let mut u = vec![vec![0.0; len]; axes];
        let mut y = vec![vec![0.0; len]; axes];
        for t in 0..len {
            for n in 0..axes {
                let e = noise.map_or(0.0, |w| w[n][t]);
                y[n][t] = (0..ns).map(|s| self.c[(n, s)] * x[s]).sum::<f64>() + e;
                u[n][t] = r[n][t] - kd * y[n][t];
            }
            for (i, v) in next.iter_mut().enumerate() {
                *v = (0..ns).map(|s| self.ad[(i, s)] * x[s]).sum::<f64>()
                    + (0..axes).map(|a| self.bd[(i, a)] * u[a][t]).sum::<f64>();
            }
            std::mem::swap(&mut x, &mut next);
        }
        Record { u, y }
    }

    /// The ZOH-sampled FRF `C (z I - Ad)^-1 Bd` at line `k` of a period of `n` samples.
    fn frf(&self, k: usize, n: usize) -> CMat {
        let z = Complex64::from_polar(1.0, 2.0 * PI * k as f64 / n as f64);
        let ns = self.ad.nrows();
        let a = CMat::from_fn(ns, ns, |i, j| {
            let diag = if i == j { z } else { Complex64::new(0.0, 0.0) };
            diag - self.ad[(i, j)]
        });
        let b = self.bd.map(|v| Complex64::new(v, 0.0));
        let x = a.lu().solve(&b).expect("z is not an eigenvalue of Ad");
        self.c.map(|v| Complex64::new(v, 0.0)) * x
    }
}

const FS: f64 = 1000.0;
const PERIOD: usize = 256;
const TRANSIENT: usize = 10;
const STEADY: usize = 8;

fn multisine(axes: usize, blocks: usize) -> OrthogonalMultisine {
    let mut d = OrthogonalMultisineDesign::new(axes, FS, PERIOD, [2.0, 120.0], 1.0);
    d.blocks = blocks;
    d.seed = 5 + axes as u64;
    d.generate().unwrap()
}

/// Every experiment played for `TRANSIENT + STEADY` periods through the plant.
fn records(ms: &OrthogonalMultisine, plant: &Plant) -> Vec<Record> {
    (0..ms.experiments())
        .map(|p| {
            let u: Vec<Vec<f64>> = (0..ms.axes)
                .map(|n| ms.repeat(p, n, TRANSIENT + STEADY))
                .collect();
            let y = plant.simulate(&u);
            Record { u, y }
        })
        .collect()
}

/// Pushes every whole period of every record.
fn push_all(est: &mut MimoEstimator, recs: &[Record], n: usize) {
    for (p, r) in recs.iter().enumerate() {
        for q in 0..r.u[0].len() / n {
            let u: Vec<&[f64]> = r.u.iter().map(|c| &c[q * n..(q + 1) * n]).collect();
            let y: Vec<&[f64]> = r.y.iter().map(|c| &c[q * n..(q + 1) * n]).collect();
            est.push_period(p, &u, &y).unwrap();
        }
    }
}

fn rel(a: Complex64, b: Complex64) -> f64 {
    (a - b).norm() / b.norm()
}

#[test]
fn noise_free_estimate_is_the_plants_sampled_frf() {
    for (axes, blocks) in [(2, 1), (2, 2), (3, 1)] {
        let ms = multisine(axes, blocks);
        let plant = Plant::chain(axes, FS);
        let recs = records(&ms, &plant);
        let mut est = MimoEstimator::from_multisine(&ms)
            .unwrap()
            .with_transient_periods(TRANSIENT);
        push_all(&mut est, &recs, PERIOD);
        let frf = est.estimate().unwrap();
        assert_eq!(frf.lines, ms.excited_lines);
        assert_eq!(frf.periods, vec![STEADY; ms.experiments()]);
        // relative error of elements down to 1e-4 of their row's diagonal, and of every
        // element relative to that diagonal (the weakest, at 1e-7 of it, are at the
        // rounding of the full-scale signals)
        let (mut worst, mut worst_weak, mut weakest) = (0.0_f64, 0.0_f64, f64::INFINITY);
        for (j, &k) in frf.lines.iter().enumerate() {
            let g0 = plant.frf(k, PERIOD);
            assert!((frf.condition[j] - 1.0).abs() < 1e-9);
            for n in 0..axes {
                for m in 0..axes {
                    let (g0_nm, diag) = (g0[(n, m)], g0[(n, n)].norm());
                    // the plant is reciprocal, so the symmetrised estimate is exact too
                    for g in [frf.g[j][(n, m)], frf.g_sym[j][(n, m)]] {
                        if g0_nm.norm() >= 1e-4 * diag {
                            worst = worst.max(rel(g, g0_nm));
                        }
                        worst_weak = worst_weak.max((g - g0_nm).norm() / diag);
                    }
                    weakest = weakest.min(g0_nm.norm() / diag);
                }
            }
        }
        eprintln!(
            "{axes} axes, {blocks} blocks: worst relative error {worst:.1e}, worst error over \
             the diagonal {worst_weak:.1e}, weakest element / diagonal {weakest:.1e}"
        );
        assert!(worst < 1e-8, "{axes} axes, {blocks} blocks: {worst:e}");
        assert!(
            worst_weak < 1e-12,
            "{axes} axes, {blocks} blocks: {worst_weak:e}"
        );
        // the off-diagonal elements reach well below the diagonal ones in the band
        if axes > 1 {
            assert!(weakest < 0.05, "{weakest}");
        }
    }
}

/// Adds white noise of `rel_u` times the RMS of each torque and `rel_y` times the RMS of
/// each velocity.
fn noisy(recs: &[Record], rel_u: f64, rel_y: f64, r: &mut StdRng) -> Vec<Record> {
    let add = |x: &[f64], rel: f64, r: &mut StdRng| -> Vec<f64> {
        let s = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        x.iter()
            .zip(gauss(r, x.len(), rel * s))
            .map(|(a, b)| a + b)
            .collect()
    };
    recs.iter()
        .map(|rec| Record {
            u: rec.u.iter().map(|c| add(c, rel_u, r)).collect(),
            y: rec.y.iter().map(|c| add(c, rel_y, r)).collect(),
        })
        .collect()
}

/// Per element `(n, m)`: the mean over lines and realisations of `|G - G0|^2 / var` (with
/// each realisation's estimated variance), the Monte-Carlo spread over the predicted
/// variance (mean over lines of `mean_r |G - G0|^2 / mean_r var`), and the mean over
/// lines of `|mean_r G - G0|^2 / (mean_r var / R)` (bias against its standard error).
struct Check {
    chi2: DMatrix<f64>,
    spread: DMatrix<f64>,
    bias: DMatrix<f64>,
    /// Sum over lines of the Monte-Carlo mean squared error.
    mse: DMatrix<f64>,
}

/// Open loop: the steady periods of the plant's response to the multisines with white
/// noise on the measured torques (2 % of their RMS) and velocities (5 %).
fn open_loop(ms: &OrthogonalMultisine, plant: &Plant) -> impl FnMut(&mut StdRng) -> Vec<Record> {
    let steady: Vec<Record> = records(ms, plant)
        .into_iter()
        .map(|r| Record {
            u: r.u
                .iter()
                .map(|c| c[TRANSIENT * PERIOD..].to_vec())
                .collect(),
            y: r.y
                .iter()
                .map(|c| c[TRANSIENT * PERIOD..].to_vec())
                .collect(),
        })
        .collect();
    move |r| noisy(&steady, 0.02, 0.05, r)
}

/// `realisations` noisy records of the experiments of `ms` from `realise`, each estimated
/// after `transient` periods, against the plant's FRF.
fn monte_carlo(
    ms: &OrthogonalMultisine,
    plant: &Plant,
    realisations: usize,
    transient: usize,
    mut realise: impl FnMut(&mut StdRng) -> Vec<Record>,
) -> (Check, Check) {
    let axes = ms.axes;
    let lines = ms.excited_lines.len();
    let g0: Vec<CMat> = ms
        .excited_lines
        .iter()
        .map(|&k| plant.frf(k, PERIOD))
        .collect();
    let mut est = MimoEstimator::from_multisine(ms)
        .unwrap()
        .with_transient_periods(transient);
    let zero_c = || vec![CMat::zeros(axes, axes); lines];
    let zero_r = || vec![DMatrix::<f64>::zeros(axes, axes); lines];
    let (mut sum_g, mut sum_s) = (zero_c(), zero_c());
    let (mut se_g, mut se_s, mut v_g, mut v_s) = (zero_r(), zero_r(), zero_r(), zero_r());
    let (mut chi_g, mut chi_s) = (
        DMatrix::<f64>::zeros(axes, axes),
        DMatrix::<f64>::zeros(axes, axes),
    );
    let mut r = rng(1000 + axes as u64);
    for _ in 0..realisations {
        est.reset();
        push_all(&mut est, &realise(&mut r), PERIOD);
        let f = est.estimate().unwrap();
        for j in 0..lines {
            for n in 0..axes {
                for m in 0..axes {
                    let e_g = (f.g[j][(n, m)] - g0[j][(n, m)]).norm_sqr();
                    let e_s = (f.g_sym[j][(n, m)] - g0[j][(n, m)]).norm_sqr();
                    sum_g[j][(n, m)] += f.g[j][(n, m)];
                    sum_s[j][(n, m)] += f.g_sym[j][(n, m)];
                    se_g[j][(n, m)] += e_g;
                    se_s[j][(n, m)] += e_s;
                    v_g[j][(n, m)] += f.var[j][(n, m)];
                    v_s[j][(n, m)] += f.var_sym[j][(n, m)];
                    chi_g[(n, m)] += e_g / f.var[j][(n, m)];
                    chi_s[(n, m)] += e_s / f.var_sym[j][(n, m)];
                }
            }
        }
    }
    let rf = realisations as f64;
    let check = |sum: &[CMat], se: &[DMatrix<f64>], v: &[DMatrix<f64>], chi: DMatrix<f64>| {
        let per_line = |f: &dyn Fn(usize, usize, usize) -> f64| {
            DMatrix::from_fn(axes, axes, |n, m| {
                (0..lines).map(|j| f(j, n, m)).sum::<f64>() / lines as f64
            })
        };
        Check {
            chi2: chi / (rf * lines as f64),
            spread: per_line(&|j, n, m| se[j][(n, m)] / v[j][(n, m)]),
            bias: per_line(&|j, n, m| {
                (sum[j][(n, m)] / rf - g0[j][(n, m)]).norm_sqr() / (v[j][(n, m)] / (rf * rf))
            }),
            mse: DMatrix::from_fn(axes, axes, |n, m| {
                (0..lines).map(|j| se[j][(n, m)]).sum::<f64>() / rf
            }),
        }
    };
    (
        check(&sum_g, &se_g, &v_g, chi_g),
        check(&sum_s, &se_s, &v_s, chi_s),
    )
}

/// The variance formula against the Monte-Carlo spread, for a square `U` (3 axes, one
/// block) and a pseudo-inverse (2 axes, two blocks): per element, also the weak
/// off-diagonal ones, the normalised squared errors average about 1 (chi-squared with two
/// degrees of freedom over two), the spread over realisations equals the predicted
/// variance, the estimate is unbiased; the symmetrised estimate has the same mean and a
/// smaller variance off the diagonal.
#[test]
fn predicted_variance_matches_the_monte_carlo_spread() {
    for (axes, blocks, reals) in [(3, 1, 200), (2, 2, 200)] {
        let ms = multisine(axes, blocks);
        let plant = Plant::chain(axes, FS);
        let (g, s) = monte_carlo(&ms, &plant, reals, 0, open_loop(&ms, &plant));
        let label = format!("open loop, {axes} axes, {blocks} blocks, {reals} realisations");
        assert_consistent(&label, &g, &s, true);
    }
}

/// The checks of one Monte Carlo run, per element; `lower_sym`: the symmetrised estimate's
/// spread is also asserted below both of its elements'.
fn assert_consistent(label: &str, g: &Check, s: &Check, lower_sym: bool) {
    let axes = g.chi2.nrows();
    eprintln!(
        "{label}\n chi2 G {:.3}\n spread G {:.3}\n bias G {:.3}\n chi2 S {:.3}\n spread S \
         {:.3}\n bias S {:.3}",
        g.chi2, g.spread, g.bias, s.chi2, s.spread, s.bias
    );
    for n in 0..axes {
        for m in 0..axes {
            for (name, c) in [("G", g), ("S", s)] {
                let at = (n, m);
                assert!(
                    (0.7..1.4).contains(&c.chi2[at]),
                    "{label}: {name} chi2 {at:?}: {}",
                    c.chi2[at]
                );
                assert!(
                    (0.85..1.15).contains(&c.spread[at]),
                    "{label}: {name} spread {at:?}: {}",
                    c.spread[at]
                );
                // |mean error|^2 over its variance: mean 1 for an unbiased estimate
                assert!(
                    c.bias[at] < 2.0,
                    "{label}: {name} bias {at:?}: {}",
                    c.bias[at]
                );
            }
            if lower_sym && n != m {
                assert!(
                    s.mse[(n, m)] < 0.75 * g.mse[(n, m)].min(g.mse[(m, n)]),
                    "{label}: symmetrised ({n}, {m}): {} vs {} {}",
                    s.mse[(n, m)],
                    g.mse[(n, m)],
                    g.mse[(m, n)]
                );
            }
        }
    }
}

/// Closed loop (the direct method under a feedback): each axis's torque is its multisine
/// minus `kd` times the measured motor velocity, and the velocity is measured with white
/// noise of `rel_y` times its RMS; the logged torque (what the estimator gets) then holds
/// the fed-back noise, correlated with the velocity's, so the variance's cross term
/// `C_yu` matters. Transient periods included (the noise drives the plant).
fn closed_loop<'a>(
    ms: &OrthogonalMultisine,
    plant: &'a Plant,
    kd: f64,
    rel_y: f64,
) -> impl FnMut(&mut StdRng) -> Vec<Record> + 'a {
    let refs: Vec<Vec<Vec<f64>>> = (0..ms.experiments())
        .map(|p| {
            (0..ms.axes)
                .map(|n| ms.repeat(p, n, TRANSIENT + STEADY))
                .collect()
        })
        .collect();
    let clean: Vec<Record> = refs
        .iter()
        .map(|r| plant.simulate_closed(r, kd, None))
        .collect();
    let sigma: Vec<Vec<f64>> = clean
        .iter()
        .map(|rec| {
            rec.y
                .iter()
                .map(|c| rel_y * (c.iter().map(|v| v * v).sum::<f64>() / c.len() as f64).sqrt())
                .collect()
        })
        .collect();
    move |r| {
        refs.iter()
            .zip(&sigma)
            .map(|(rp, sp)| {
                let noise: Vec<Vec<f64>> = sp.iter().map(|&s| gauss(r, rp[0].len(), s)).collect();
                plant.simulate_closed(rp, kd, Some(&noise))
            })
            .collect()
    }
}

/// The variance formula in closed loop, where the torque's noise is the fed-back velocity
/// noise: 3 axes, one block.
#[test]
fn predicted_variance_holds_in_closed_loop() {
    let ms = multisine(3, 1);
    let plant = Plant::chain(3, FS);
    let realise = closed_loop(&ms, &plant, 0.2, 0.1);
    let (g, s) = monte_carlo(&ms, &plant, 150, TRANSIENT, realise);
    assert_consistent(
        "closed loop, 3 axes, 1 block, 150 realisations",
        &g,
        &s,
        false,
    );
}

/// Straightforward reference: the direct DFT of every steady period, two-pass means and
/// covariances, `G` by the normal equations, the variances by explicit sums.
fn naive(
    recs: &[Record],
    n: usize,
    transient: usize,
    lines: &[usize],
) -> Vec<(CMat, DMatrix<f64>, CMat, DMatrix<f64>)> {
    let axes = recs[0].u.len();
    let c = 2 * axes;
    let czero = Complex64::new(0.0, 0.0);
    lines
        .iter()
        .map(|&k| {
            let mut means = Vec::new();
            let mut covs = Vec::new();
            for r in recs {
                let periods: Vec<usize> = (transient..r.u[0].len() / n).collect();
                let m = periods.len() as f64;
                let zs: Vec<Vec<Complex64>> = periods
                    .iter()
                    .map(|&q| {
                        r.u.iter()
                            .chain(&r.y)
                            .map(|x| dft_line(&x[q * n..(q + 1) * n], k) / n as f64)
                            .collect()
                    })
                    .collect();
                let mean: Vec<Complex64> = (0..c)
                    .map(|a| zs.iter().map(|z| z[a]).sum::<Complex64>() / m)
                    .collect();
                let cov = CMat::from_fn(c, c, |a, b| {
                    zs.iter()
                        .map(|z| (z[a] - mean[a]) * (z[b] - mean[b]).conj())
                        .sum::<Complex64>()
                        / ((m - 1.0) * m)
                });
                means.push(mean);
                covs.push(cov);
            }
            let p = recs.len();
            let u = CMat::from_fn(axes, p, |a, e| means[e][a]);
            let y = CMat::from_fn(axes, p, |a, e| means[e][axes + a]);
            let pinv = u.adjoint() * (&u * u.adjoint()).try_inverse().unwrap();
            let g = &y * &pinv;
            let t = |row: usize, col: usize| -> Complex64 {
                if col < axes {
                    -g[(row, col)]
                } else if col - axes == row {
                    Complex64::new(1.0, 0.0)
                } else {
                    czero
                }
            };
            // E[e_p[a] conj(e_p[b])] = sum_ij T[a,i] C[i,j] conj(T[b,j])
            let ce = |e: usize, a: usize, b: usize| -> Complex64 {
                let mut s = czero;
                for i in 0..c {
                    for j in 0..c {
                        s += t(a, i) * covs[e][(i, j)] * t(b, j).conj();
                    }
                }
                s
            };
            let var = DMatrix::from_fn(axes, axes, |a, m| {
                (0..p)
                    .map(|e| pinv[(e, m)].norm_sqr() * ce(e, a, a).re)
                    .sum::<f64>()
            });
            let g_sym = CMat::from_fn(axes, axes, |a, m| (g[(a, m)] + g[(m, a)]) / 2.0);
            let var_sym = DMatrix::from_fn(axes, axes, |a, m| {
                if a == m {
                    return var[(a, a)];
                }
                let cross: Complex64 = (0..p)
                    .map(|e| pinv[(e, m)] * pinv[(e, a)].conj() * ce(e, a, m))
                    .sum();
                (var[(a, m)] + var[(m, a)] + 2.0 * cross.re) / 4.0
            });
            (g, var, g_sym, var_sym)
        })
        .collect()
}

/// Synthetic records (any data will do for the reference): torques with noise, each
/// velocity a resonator's response to a mix of the torques plus noise; garbage in the
/// transient periods; experiments with different numbers of periods.
fn synthetic(ms: &OrthogonalMultisine, transient: usize) -> Vec<Record> {
    let mut r = rng(77);
    let n = ms.period_samples();
    (0..ms.experiments())
        .map(|p| {
            let total = transient + 3 + p;
            let mut u: Vec<Vec<f64>> = (0..ms.axes)
                .map(|a| {
                    let x = ms.repeat(p, a, total);
                    x.iter()
                        .zip(gauss(&mut r, x.len(), 0.05))
                        .map(|(v, e)| v + e)
                        .collect()
                })
                .collect();
            let y: Vec<Vec<f64>> = (0..ms.axes)
                .map(|a| {
                    let mix: Vec<f64> = (0..u[0].len())
                        .map(|t| {
                            (0..ms.axes)
                                .map(|b| u[b][t] / (1.0 + (a + 2 * b) as f64))
                                .sum()
                        })
                        .collect();
                    let resp = Biquad::resonator(0.9, 0.05 + 0.03 * a as f64).run(&mix);
                    resp.iter()
                        .zip(gauss(&mut r, mix.len(), 0.02))
                        .map(|(v, e)| v + e)
                        .collect()
                })
                .collect();
            for c in u.iter_mut() {
                c[..transient * n].iter_mut().for_each(|v| *v = 1e6);
            }
            Record { u, y }
        })
        .collect()
}

#[test]
fn fast_path_matches_a_naive_dft_reference() {
    for (axes, blocks) in [(2, 2), (3, 1)] {
        let mut d = OrthogonalMultisineDesign::new(axes, FS, 64, [20.0, 300.0], 1.0);
        d.blocks = blocks;
        d.rms_nm = (0..axes).map(|a| 1.0 + 0.5 * a as f64).collect();
        let ms = d.generate().unwrap();
        let transient = 2;
        let recs = synthetic(&ms, transient);
        let mut est = MimoEstimator::from_multisine(&ms)
            .unwrap()
            .with_transient_periods(transient);
        push_all(&mut est, &recs, 64);
        let got = est.estimate().unwrap();
        let want = naive(&recs, 64, transient, &ms.excited_lines);
        assert_eq!(
            got.periods,
            (0..ms.experiments()).map(|p| 3 + p).collect::<Vec<_>>()
        );
        for (j, (g, var, g_sym, var_sym)) in want.iter().enumerate() {
            let scale = g.iter().map(|v| v.norm()).fold(0.0, f64::max);
            let vscale = var.iter().cloned().fold(0.0, f64::max);
            for a in 0..axes {
                for m in 0..axes {
                    let at = (a, m);
                    assert!((got.g[j][at] - g[at]).norm() < 1e-10 * scale, "G line {j}");
                    assert!((got.g_sym[j][at] - g_sym[at]).norm() < 1e-10 * scale);
                    assert!(
                        (got.var[j][at] - var[at]).abs() < 1e-9 * vscale,
                        "var line {j}"
                    );
                    assert!((got.var_sym[j][at] - var_sym[at]).abs() < 1e-9 * vscale);
                    assert!(var[at] > 0.0 && var_sym[at] > 0.0);
                }
            }
        }
    }
}

#[test]
fn one_steady_period_gives_infinite_variance() {
    let ms = multisine(2, 1);
    let recs = records(&ms, &Plant::chain(2, FS));
    let mut est = MimoEstimator::from_multisine(&ms)
        .unwrap()
        .with_transient_periods(TRANSIENT + STEADY - 1);
    push_all(&mut est, &recs, PERIOD);
    let f = est.estimate().unwrap();
    assert_eq!(f.periods, vec![1, 1]);
    assert!(f.var.iter().all(|v| v.iter().all(|x| x.is_infinite())));
    assert!(f.var_sym.iter().all(|v| v.iter().all(|x| x.is_infinite())));
    let e = f.element(0, 1, true, FrfKind::Velocity);
    assert_eq!(e.h.len(), f.len());
    assert_eq!(e.h[3], f.g_sym[3][(0, 1)]);
}

#[test]
fn errors_not_panics() {
    let fs = 1000.0;
    assert!(matches!(
        MimoEstimator::new(0, 64, &[1], 1, fs),
        Err(MimoError::InvalidParameter { name: "axes", .. })
    ));
    assert!(matches!(
        MimoEstimator::new(2, 64, &[1], 2, -1.0),
        Err(MimoError::InvalidParameter {
            name: "sample_rate_hz",
            ..
        })
    ));
    assert_eq!(
        MimoEstimator::new(2, 64, &[], 2, fs).unwrap_err(),
        MimoError::NoLines
    );
    assert_eq!(
        MimoEstimator::new(2, 64, &[0, 3], 2, fs).unwrap_err(),
        MimoError::LineOutOfRange { line: 0, max: 31 }
    );
    assert_eq!(
        MimoEstimator::new(2, 64, &[3, 32], 2, fs).unwrap_err(),
        MimoError::LineOutOfRange { line: 32, max: 31 }
    );
    assert_eq!(
        MimoEstimator::new(3, 64, &[3], 2, fs).unwrap_err(),
        MimoError::TooFewExperiments {
            axes: 3,
            experiments: 2
        }
    );
    let mut est = MimoEstimator::new(2, 64, &[3, 5], 2, fs).unwrap();
    let a = vec![0.0; 64];
    let short = vec![0.0; 63];
    let two: Vec<&[f64]> = vec![&a, &a];
    assert_eq!(
        est.push_period(2, &two, &two),
        Err(MimoError::ExperimentOutOfRange {
            experiment: 2,
            experiments: 2
        })
    );
    assert_eq!(
        est.push_period(0, &[&a], &two),
        Err(MimoError::ChannelCount {
            signal: "u",
            expected: 2,
            got: 1
        })
    );
    assert_eq!(
        est.push_period(0, &two, &[&a, &short]),
        Err(MimoError::ChannelLength {
            signal: "y",
            channel: 1,
            expected: 64,
            got: 63
        })
    );
    assert_eq!(est.periods_done(0), 0);
    est.push_period(0, &two, &two).unwrap();
    assert_eq!(
        est.estimate().unwrap_err(),
        MimoError::NoSteadyPeriod {
            experiment: 1,
            pushed: 0,
            transient_periods: 0
        }
    );
    // the same torques in both experiments: U has rank 1 at every line
    let ms = multisine(2, 1);
    let n = ms.period_samples();
    let mut est = MimoEstimator::from_multisine(&ms).unwrap();
    let u: Vec<&[f64]> = vec![ms.period(0, 0), ms.period(0, 1)];
    let y: Vec<&[f64]> = vec![ms.period(1, 0), ms.period(1, 1)];
    est.push_period(0, &u, &y).unwrap();
    est.push_period(1, &u, &y).unwrap();
    match est.estimate() {
        Err(MimoError::RankDeficient {
            line, condition, ..
        }) => {
            assert_eq!(line, ms.excited_lines[0]);
            assert!(condition > MAX_INPUT_CONDITION, "{condition}");
        }
        other => panic!("expected RankDeficient, got {other:?}"),
    }
    assert_eq!(n, PERIOD);
    // a NaN sample reaches every line's mean
    let mut est = MimoEstimator::from_multisine(&ms).unwrap();
    let mut bad = ms.period(1, 1).to_vec();
    bad[7] = f64::NAN;
    est.push_period(0, &u, &y).unwrap();
    est.push_period(1, &[ms.period(1, 0), &bad], &y).unwrap();
    assert!(matches!(
        est.estimate(),
        Err(MimoError::NonFinite { line, .. }) if line == ms.excited_lines[0]
    ));
}

//! Local polynomial method (LPM) for one non-periodic record, e.g. a single swept sine.
//!
//! The DFT of the whole record (no window) obeys, at every line `k`,
//! `Y(k) = G(k) U(k) + T(k) + V(k)`: the response, a transient term `T` (the record does
//! not start and end at rest: leakage and the initial/final conditions, smooth in
//! frequency because it shares the system's poles) and noise `V`. Around each line,
//! `G(k + r)` and `T(k + r)` are polynomials of degree [`DEGREE`] in `r`; the `2(R+1)`
//! coefficients are fitted by least squares to the [`HALF_WIDTH`]`·2 + 1` lines of the
//! window, `G(k)` is the constant term, and the residual gives the noise variance with
//! `q = 2n + 1 - 2(R + 1)` complex degrees of freedom (Pintelon, Schoukens, Vandersteen,
//! Barbé, "Estimation of nonparametric noise and FRF models for multivariable systems",
//! MSSP 24 (2010)):
//!
//! `σ²_V = |e|²/q`, `var G(k) = σ²_V [(K^H K)^{-1}]_00`.
//!
//! Where a Welch estimate smears a sweep's resonances over its segment's resolution and
//! leaks its non-stationarity into a bias its coherence-based variance does not hold, the
//! LPM keeps the record's full resolution and a variance that holds: on a world sweep the
//! mean `|G - G_true|²/var` over 746 lines was 1.06, the `F(2, 2q)` mean 1.12 (Welch with
//! its own variance: 4.6 around the resonances).
//!
//! **The known shape of a mechanical axis.** A polynomial in `r` cannot follow `1/ω` where
//! the window is a sizeable part of the frequency itself: at 3 Hz with 2 Hz windows the
//! quadratic misses a rigid body's velocity response by 0.2 dB, dozens of standard
//! deviations of a slow sweep's low lines. So the polynomial models `G(k)·(jω_k)^p`, the
//! response with its asymptote divided out (`p` = 2 for position, 1 for velocity, 0 for
//! anything else, from the FRF kind): each window's regressor is `U(k+r)·(k/(k+r))^p`,
//! equal to `U` at the centre line, so the constant term is still `G(k)` and the
//! variance formula is unchanged. Where the response does not follow the asymptote (a
//! resonance), the remaining curvature is what the polynomial took before.
//!
//! **An encoder's count error.** Where the response is a few counts, the recorded
//! signal's count error follows the sweep instead of scattering about it, and the
//! windows' residual misses it (a resonance peaking at 3 counts: mean `z²` 115 against the
//! exact response). Where the signal lies on a grid of step `q`, the error's level `q²/12`
//! per sample is added to each line's noise ([`estimate_lpm_with_floor`]): an upper bound
//! on the part the residual missed, which at most doubles the variance where the error
//! scatters like noise and the residual holds it already.
//!
//! Windows do not overlap: each line's estimate uses its own `2n + 1` DFT lines, so the
//! estimates are independent (the diagnosis's noise floor sums them as independent lines)
//! and spaced `(2n + 1) fs / N` apart.

use super::error::{check_fs, FrfError};
use super::types::{Frf, FrfKind};
use nalgebra::{SMatrix, SVector};
use num_complex::Complex64;
use realfft::RealFftPlanner;

/// Polynomial degree `R` of `G` and `T` in each window: 2, the usual choice (degree 1
/// leaves the curvature of a resonance in the noise estimate; degree 3 and 4 with the
/// same dof need wider windows, and their least squares grow ill-conditioned where the
/// sweep's input is small).
pub const DEGREE: usize = 2;

/// Half-width `n` of a window: `2n + 1 = 15` lines for `q = 9` complex degrees of freedom
/// of the noise variance (with `n = 3`, the minimum, `q = 1` and the line `z²` would be
/// `F(2, 2)`, whose mean is infinite).
pub const HALF_WIDTH: usize = 7;

/// Unknowns per window: `G` and `T`, each `R + 1` coefficients.
const UNKNOWNS: usize = 2 * (DEGREE + 1);

/// Complex degrees of freedom of each line's noise variance, `2n + 1 - 2(R + 1)`.
pub const fn lpm_dof() -> usize {
    2 * HALF_WIDTH + 1 - UNKNOWNS
}

/// The LPM estimate of `y / u` over the whole record at the lines whose window centre lies
/// in `band_hz` (all lines from 1 to Nyquist when `None`), one line per window of
/// `2 HALF_WIDTH + 1` DFT lines.
///
/// Errors: `TooShort` when the record holds fewer than one window, `LengthMismatch` for
/// different lengths, `InvalidParameter` for a bad sample rate, `NoExcitedLines` when no
/// window lies in the band.
pub fn estimate_lpm(
    u: &[f64],
    y: &[f64],
    sample_rate_hz: f64,
    kind: FrfKind,
    band_hz: Option<[f64; 2]>,
) -> Result<Frf, FrfError> {
    estimate_lpm_with_floor(u, y, sample_rate_hz, kind, band_hz, 0.0)
}

/// [`estimate_lpm`] with an error of variance `floor_var` per sample in the recorded
/// signal (before `kind`'s differencing) that the windows' residual does not see, added to
/// each line's noise variance: an encoder's count error, which follows the signal instead
/// of scattering about it ([`super::quantisation`]). Its DFT over `N` samples has variance
/// `N floor_var |D(ω)|²` per DFT line (`D` the differencing of a position), taken through
/// the window's least squares as the residual's variance is.
pub fn estimate_lpm_with_floor(
    u: &[f64],
    y: &[f64],
    sample_rate_hz: f64,
    kind: FrfKind,
    band_hz: Option<[f64; 2]>,
    floor_var: f64,
) -> Result<Frf, FrfError> {
    check_fs(sample_rate_hz)?;
    if u.len() != y.len() {
        return Err(FrfError::LengthMismatch {
            u: u.len(),
            y: y.len(),
        });
    }
    let n = u.len();
    let width = 2 * HALF_WIDTH + 1;
    if n / 2 < width + 1 {
        return Err(FrfError::TooShort {
            needed: 2 * (width + 1),
            got: n,
            unit: "samples",
        });
    }
    // one plan for both signals
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let spectrum = |x: &[f64]| {
        let mut input = x.to_vec();
        let mut out = fft.make_output_vec();
        fft.process(&mut input, &mut out)
            .expect("buffer lengths from the plan");
        out
    };
    let (su, sy) = (spectrum(u), spectrum(y));
    let df = sample_rate_hz / n as f64;
    let mut frf = Frf {
        freq_hz: Vec::new(),
        h: Vec::new(),
        var: Vec::new(),
        coherence: None,
        kind,
        sample_rate_hz,
    };
    for (k, f) in window_centres(su.len(), df, band_hz.unwrap_or([df, sample_rate_hz / 2.0])) {
        let floor_line = n as f64
            * super::quantisation::line_variance(floor_var, kind, f, sample_rate_hz, 1, 1.0.into());
        if let Some((g, var)) = window_fit(
            &su[k - HALF_WIDTH..=k + HALF_WIDTH],
            &sy[k - HALF_WIDTH..=k + HALF_WIDTH],
            k,
            asymptote_power(kind),
            floor_line,
        ) {
            frf.freq_hz.push(f);
            frf.h.push(g);
            frf.var.push(var);
        }
    }
    if frf.is_empty() {
        return Err(FrfError::NoExcitedLines);
    }
    Ok(frf)
}

/// The centre lines `k` of the windows and their frequencies [Hz] in `[lo, hi]`: windows
/// `[k - n, k + n]` tile a spectrum of `lines` DFT lines `df` [Hz] apart from line 1 (DC
/// left out) to the last full window, without overlap.
pub(super) fn window_centres(
    lines: usize,
    df: f64,
    [lo, hi]: [f64; 2],
) -> impl Iterator<Item = (usize, f64)> {
    let last = lines.saturating_sub(1);
    (1 + HALF_WIDTH..)
        .step_by(2 * HALF_WIDTH + 1)
        .take_while(move |k| k + HALF_WIDTH <= last)
        .map(move |k| (k, k as f64 * df))
        .filter(move |&(_, f)| f >= lo && f <= hi)
}

/// The power `p` of the high- and low-frequency asymptote `1/(jω)^p` of a mechanical axis's
/// response of this kind (see the module's documentation).
fn asymptote_power(kind: FrfKind) -> i32 {
    match kind {
        FrfKind::Position => 2,
        FrfKind::Velocity | FrfKind::DifferencedVelocity => 1,
        FrfKind::Other => 0,
    }
}

/// One window's least squares as far as the input fixes it: the input's scale, the
/// regressor's rows (one per line of the window) and the inverse of the normal matrix.
struct WindowSystem {
    scale: f64,
    rows: [SVector<Complex64, UNKNOWNS>; 2 * HALF_WIDTH + 1],
    inv: SMatrix<Complex64, UNKNOWNS, UNKNOWNS>,
}

/// The least squares of the window of input lines `u` (centre line `centre` in the
/// middle), the polynomial taken on `G·(jω)^power`; `None` when the input is zero or the
/// normal matrix singular.
fn window_system(u: &[Complex64], centre: usize, power: i32) -> Option<WindowSystem> {
    let scale = u.iter().map(|v| v.norm()).fold(0.0_f64, f64::max);
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    // (k/(k+r))^p: the asymptote divided out, 1 at the centre line; it multiplies both the
    // input (U) and the transient's polynomial (T shares the system's poles: a free body's
    // position drifts, and its leakage grows as 1/ω² towards DC)
    let asymptote = |i: usize| {
        let line = (centre + i) as f64 - HALF_WIDTH as f64;
        (centre as f64 / line).powi(power)
    };
    let shaped = |i: usize| u[i] / scale * asymptote(i);
    let row = |i: usize| {
        // r in [-1, 1] for conditioning; the constant terms are what is read
        let r = (i as f64 - HALF_WIDTH as f64) / HALF_WIDTH as f64;
        let mut k = SVector::<Complex64, UNKNOWNS>::zeros();
        let mut p = 1.0;
        for s in 0..=DEGREE {
            k[s] = shaped(i) * p;
            k[DEGREE + 1 + s] = Complex64::new(p * asymptote(i), 0.0);
            p *= r;
        }
        k
    };
    let rows: [SVector<Complex64, UNKNOWNS>; 2 * HALF_WIDTH + 1] = std::array::from_fn(row);
    let mut normal = SMatrix::<Complex64, UNKNOWNS, UNKNOWNS>::zeros();
    for k in &rows {
        normal += k.conjugate() * k.transpose();
    }
    let inv = normal.try_inverse()?;
    Some(WindowSystem { scale, rows, inv })
}

/// `G(k)` and its variance from one window of `2n + 1` lines of `U` and `Y` (centre line
/// `centre` in the middle), the polynomial taken on `G·(jω)^power`; `None` when the input
/// is zero or the fit is singular.
fn window_fit(
    u: &[Complex64],
    y: &[Complex64],
    centre: usize,
    power: i32,
    floor_line: f64,
) -> Option<(Complex64, f64)> {
    let WindowSystem { scale, rows, inv } = window_system(u, centre, power)?;
    let mut rhs = SVector::<Complex64, UNKNOWNS>::zeros();
    for (k, yi) in rows.iter().zip(y) {
        rhs += k.conjugate() * *yi;
    }
    let theta = inv * rhs;
    let rss: f64 = y
        .iter()
        .zip(&rows)
        .map(|(yi, k)| (yi - k.dot(&theta)).norm_sqr())
        .sum();
    let s2 = rss / lpm_dof() as f64 + floor_line;
    let g = theta[0] / scale;
    let var = s2 * inv[(0, 0)].re / (scale * scale);
    (g.re.is_finite() && g.im.is_finite() && var.is_finite() && var > 0.0).then_some((g, var))
}

/// The weights `w` of one window (input lines `u`, centre line `centre`, the response of
/// `kind`) that give its estimate from the response's lines: `G(k) = Σᵢ wᵢ Y(k - n + i)`,
/// the first row of `(KᴴK)⁻¹ Kᴴ` over the input's scale ([`super::LpmPlan`]); `None` where
/// [`estimate_lpm`] has no line for any response.
pub(super) fn window_weights(
    u: &[Complex64],
    centre: usize,
    kind: FrfKind,
) -> Option<[Complex64; 2 * HALF_WIDTH + 1]> {
    let WindowSystem { scale, rows, inv } = window_system(u, centre, asymptote_power(kind))?;
    let w = std::array::from_fn(|i| {
        (0..UNKNOWNS)
            .map(|j| inv[(0, j)] * rows[i][j].conj())
            .sum::<Complex64>()
            / scale
    });
    Some(w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::excitation::ChirpDesign;
    use crate::frf::test_rng::lcg;

    /// A lightly damped resonance y[k] = a1 y[k-1] + a2 y[k-2] + b u[k], its exact response.
    fn resonance(u: &[f64], fs: f64, f0: f64, zeta: f64) -> (Vec<f64>, impl Fn(f64) -> Complex64) {
        let w = 2.0 * std::f64::consts::PI * f0 / fs;
        let rho = (-zeta * w).exp();
        let (a1, a2, b) = (
            2.0 * rho * (w * (1.0 - zeta * zeta).sqrt()).cos(),
            -rho * rho,
            0.01,
        );
        let mut y = vec![0.0; u.len()];
        for k in 0..u.len() {
            let y1 = if k >= 1 { y[k - 1] } else { 0.0 };
            let y2 = if k >= 2 { y[k - 2] } else { 0.0 };
            y[k] = a1 * y1 + a2 * y2 + b * u[k];
        }
        let exact = move |f: f64| {
            let z1 = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f / fs);
            b / (1.0 - a1 * z1 - a2 * z1 * z1)
        };
        (y, exact)
    }

    fn sweep(fs: f64, secs: f64) -> Vec<f64> {
        let mut c = ChirpDesign::new(fs, 1.0, 0.4 * fs, secs, 1.0);
        c.taper_s = 0.05 * secs;
        c.generate().unwrap().signal
    }

    /// Without noise the estimate is the exact response (the record ends with the resonance
    /// still ringing: the transient term takes it), to the polynomial's approximation: that
    /// is the method's known limit, a bias where a resonance is narrower than the window
    /// (here half-power width 1.6 Hz against a 1.9 Hz window: 5 % at the peak line, under
    /// 1 % within 3 half-widths, under 0.2 % elsewhere).
    #[test]
    fn a_noise_free_sweep_gives_the_exact_response() {
        let fs = 1000.0;
        let u = sweep(fs, 8.0);
        let (f0, zeta) = (40.0, 0.02);
        let (y, exact) = resonance(&u, fs, f0, zeta);
        let frf = estimate_lpm(&u, &y, fs, FrfKind::Other, Some([2.0, 300.0])).unwrap();
        assert!(frf.len() > 100);
        for (f, h) in frf.freq_hz.iter().zip(&frf.h) {
            let e = (h / exact(*f) - 1.0).norm();
            let near = (f - f0).abs();
            let bound = if near < zeta * f0 {
                0.06
            } else if near < 3.0 * zeta * f0 {
                0.01
            } else {
                2e-3
            };
            assert!(e < bound, "{f} Hz: relative error {e}");
        }
        assert!(frf.freq_hz.windows(2).all(|w| w[1] > w[0]));
        assert!(frf.freq_hz[0] >= 2.0 && *frf.freq_hz.last().unwrap() <= 300.0);
    }

    /// A sweep read through an encoder: where the response is a few counts, the count
    /// error follows the sweep and the windows' residual misses it (a resonance peaking at 3
    /// counts: mean `z²` against the exact response 115, the `F(2, 18)` mean being 1.125);
    /// with the count error's level `q²/12` per sample added to each line's noise, it is
    /// 3.8. Where the response is a thousand counts the error scatters like noise and the
    /// residual holds it already: the floor at most doubles the variance there (mean `z²`
    /// 1.1 -> 0.5), a conservative bound, never an understated one. The floor spreads the
    /// error over every line; a sweep plays one tone at a time, and on that tone the counts
    /// make a gain error ([`crate::frf::quantisation::add_sweep_tone_variance`]): with it,
    /// mean `z²` 3.8 -> 0.26 at 3 counts (the bound over the tone's amplitude and offset is
    /// conservative: at the measured amplitude alone 1.9), 0.69 -> 0.44 at 30 counts, and
    /// unchanged at a thousand.
    #[test]
    fn a_coarse_encoder_s_count_error_is_in_the_variance() {
        let fs = 1000.0;
        let u = sweep(fs, 8.0);
        let (y, exact) = resonance(&u, fs, 40.0, 0.05);
        let peak = y.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let mean_z2 = |counts_at_peak: f64, with_floor: bool, tone: bool| {
            let q = peak / counts_at_peak;
            let mut s = 3u64;
            let counts: Vec<f64> = y
                .iter()
                .map(|v| ((v + 0.02 * q * (lcg(&mut s) - 0.5)) / q).round() * q)
                .collect();
            let floor = if with_floor { q * q / 12.0 } else { 0.0 };
            let band = Some([2.0, 300.0]);
            let mut frf =
                estimate_lpm_with_floor(&u, &counts, fs, FrfKind::Other, band, floor).unwrap();
            if tone {
                crate::frf::quantisation::add_sweep_tone_variance(&mut frf, q, &u);
            }
            let z: Vec<f64> = frf
                .freq_hz
                .iter()
                .zip(&frf.h)
                .zip(&frf.var)
                .map(|((f, h), v)| (h - exact(*f)).norm_sqr() / v)
                .collect();
            z.iter().sum::<f64>() / z.len() as f64
        };
        let (coarse, coarse_floor) = (mean_z2(3.0, false, false), mean_z2(3.0, true, false));
        let (fine, fine_floor) = (mean_z2(1000.0, false, false), mean_z2(1000.0, true, false));
        let (coarse_tone, fine_tone) = (mean_z2(3.0, true, true), mean_z2(1000.0, true, true));
        let c30 = mean_z2(30.0, true, false);
        let c30t = mean_z2(30.0, true, true);
        println!("mean z2, 3 counts at the peak: {coarse:.2} -> {coarse_floor:.2} -> tone {coarse_tone:.2}; 30 counts {c30:.2} -> tone {c30t:.2}; 1000 counts: {fine:.2} -> {fine_floor:.2} -> tone {fine_tone:.2}");
        assert!(coarse > 50.0, "{coarse}");
        assert!(coarse_floor < 0.1 * coarse, "{coarse_floor} of {coarse}");
        assert!(fine < 1.5, "{fine}");
        assert!(fine_floor > 0.4 && fine_floor < fine, "{fine_floor}");
        // the tone's error where the counts are few: the variance no longer understated
        assert!(coarse_tone < 1.125 && coarse_tone > 0.1, "{coarse_tone}");
        assert!(c30t <= c30 && c30t > 0.3, "{c30t} of {c30}");
        assert!(
            (fine_tone / fine_floor - 1.0).abs() < 0.05,
            "{fine_tone} of {fine_floor}"
        );
    }

    /// A rigid body's velocity `1/(J jω + b)` under a slow sweep: the low lines, where a
    /// window spans a good part of the frequency, are exact once the `1/ω` asymptote is
    /// divided out (a plain quadratic in the same windows misses them by several times
    /// more; on a world sweep whose first window sat below an anti-resonance, 0.38 dB
    /// against 0.09 dB).
    #[test]
    fn a_rigid_body_is_exact_at_the_low_lines() {
        let fs = 1000.0;
        let u = sweep(fs, 8.0);
        // v[k] = a v[k-1] + c u[k]: a pole at 0.2 Hz
        let a = (-2.0 * std::f64::consts::PI * 0.2 / fs).exp();
        let c = 1e-3;
        let mut y = vec![0.0; u.len()];
        for k in 0..u.len() {
            y[k] = c * u[k] + if k > 0 { a * y[k - 1] } else { 0.0 };
        }
        let exact = |f: f64| {
            c / (1.0 - a * Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f / fs))
        };
        let worst = |kind| {
            let frf = estimate_lpm(&u, &y, fs, kind, Some([1.5, 300.0])).unwrap();
            assert!(frf.freq_hz[0] < 3.0);
            frf.freq_hz
                .iter()
                .zip(&frf.h)
                .map(|(f, h)| (h / exact(*f) - 1.0).norm())
                .fold(0.0_f64, f64::max)
        };
        let (shaped, plain) = (worst(FrfKind::Velocity), worst(FrfKind::Other));
        assert!(shaped < 2e-4, "with the asymptote: worst {shaped}");
        assert!(plain > 2.0 * shaped, "plain quadratic: worst {plain}");
    }

    /// A free body's position under a sweep from rest: the record ends far from where it
    /// started (the body drifts), and that transient's leakage grows as `1/ω²` towards DC.
    /// With the asymptote divided out of the transient's polynomial as well as the input's,
    /// the lowest lines are exact; with it on the input only (the first version) the first
    /// windows were off by far more than a line's noise (world sweeps without an effect:
    /// mean `z²` 40-370 on the lowest three lines).
    #[test]
    fn a_drifting_free_body_is_exact_at_the_low_lines() {
        let fs = 1000.0;
        let secs = 8.0;
        let mut c = ChirpDesign::new(fs, 0.5, 0.4 * fs, secs, 1.0);
        c.taper_s = 0.0;
        let u = c.generate().unwrap().signal;
        // x[k] = 2 x[k-1] - x[k-2] + c u[k]: a double integrator from rest
        let gain = 1e-6;
        let mut y = vec![0.0; u.len()];
        for k in 0..u.len() {
            let x1 = if k >= 1 { y[k - 1] } else { 0.0 };
            let x2 = if k >= 2 { y[k - 2] } else { 0.0 };
            y[k] = 2.0 * x1 - x2 + gain * u[k];
        }
        assert!(y.last().unwrap().abs() > 1e-3 * y.iter().fold(0.0_f64, |m, v| m.max(v.abs())));
        let exact = |f: f64| {
            let z1 = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f / fs);
            gain / ((1.0 - z1) * (1.0 - z1))
        };
        let frf = estimate_lpm(&u, &y, fs, FrfKind::Position, Some([0.5, 300.0])).unwrap();
        assert!(frf.freq_hz[0] < 2.0, "{:?}", &frf.freq_hz[..3]);
        for (f, h) in frf.freq_hz.iter().zip(&frf.h).take(20) {
            let e = (h / exact(*f) - 1.0).norm();
            assert!(e < 1e-3, "{f} Hz: relative error {e}");
        }
    }

    /// With output noise, `|G - G_true|²/var` has the `F(2, 2q)` mean `q/(q-1)` (Monte Carlo
    /// over lines and records), where a Welch estimate of the same record is biased.
    #[test]
    fn the_variance_holds_on_a_noisy_sweep() {
        let fs = 1000.0;
        let mut s = 5u64;
        let mut z2 = Vec::new();
        for _ in 0..4 {
            let u = sweep(fs, 8.0);
            let (mut y, exact) = resonance(&u, fs, 40.0, 0.02);
            for v in y.iter_mut() {
                *v += 2e-4 * (lcg(&mut s) - 0.5);
            }
            let frf = estimate_lpm(&u, &y, fs, FrfKind::Other, Some([2.0, 300.0])).unwrap();
            for i in 0..frf.len() {
                z2.push((frf.h[i] - exact(frf.freq_hz[i])).norm_sqr() / frf.var[i]);
            }
        }
        let mean = z2.iter().sum::<f64>() / z2.len() as f64;
        let q = lpm_dof() as f64;
        let expect = q / (q - 1.0);
        // the mean of ~1000 F(2, 18) lines: standard deviation about 0.04
        assert!(
            (mean / expect - 1.0).abs() < 0.15,
            "mean z2 {mean}, F mean {expect}"
        );
    }

    #[test]
    fn a_short_record_is_an_error() {
        let r = estimate_lpm(&[0.0; 20], &[0.0; 20], 1000.0, FrfKind::Other, None);
        assert!(matches!(r, Err(FrfError::TooShort { .. })), "{r:?}");
        let r = estimate_lpm(&[0.0; 20], &[0.0; 21], 1000.0, FrfKind::Other, None);
        assert!(matches!(r, Err(FrfError::LengthMismatch { .. })), "{r:?}");
    }
}

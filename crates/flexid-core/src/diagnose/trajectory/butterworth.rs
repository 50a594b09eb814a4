//! A digital Butterworth low-pass (bilinear transform with the cut-off prewarped) as a
//! cascade of second-order sections, and its zero-phase forward-backward application: the
//! "bandpass filtering" of the position and the "parallel filtering" of the force in the
//! IDIM literature (Gautier 1997; Janot, Gautier & Brunot 2019, sections 3.1-3.2).

/// One second-order section `(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)` (a first
/// order one has `b2 = a2 = 0`), run in transposed direct form II.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    pub b: [f64; 3],
    pub a: [f64; 2],
}

impl Section {
    /// The section's response at `z = e^(j w)`, `w` [rad/sample].
    fn response(&self, w: f64) -> num_complex::Complex64 {
        let z1 = num_complex::Complex64::from_polar(1.0, -w);
        let z2 = z1 * z1;
        (self.b[0] + self.b[1] * z1 + self.b[2] * z2) / (1.0 + self.a[0] * z1 + self.a[1] * z2)
    }

    /// The states that a constant input `u` holds at rest (the output is then `g u`,
    /// `g` the DC gain): the start that makes a filter begin without a step transient.
    fn rest_state(&self, u: f64) -> [f64; 2] {
        let g = (self.b[0] + self.b[1] + self.b[2]) / (1.0 + self.a[0] + self.a[1]);
        let y = g * u;
        let s2 = self.b[2] * u - self.a[1] * y;
        let s1 = self.b[1] * u - self.a[0] * y + s2;
        [s1, s2]
    }
}

/// A Butterworth low-pass of `order` poles, cut-off `cutoff_hz` at `sample_rate_hz`.
#[derive(Debug, Clone, PartialEq)]
pub struct Butterworth {
    pub order: usize,
    pub cutoff_hz: f64,
    pub sample_rate_hz: f64,
    pub sections: Vec<Section>,
}

impl Butterworth {
    /// The design: analog prototype poles `p_k = W e^(j pi (2k + n + 1) / (2n))` with the
    /// prewarped cut-off `W = 2 fs tan(pi fc / fs)`, conjugate pairs as sections
    /// `W² / (s² - 2 Re(p) s + W²)` (and `W / (s + W)` for odd orders), each mapped by the
    /// bilinear transform `s = 2 fs (z - 1)/(z + 1)`. Every section has unit DC gain.
    /// `None` unless `0 < fc < fs/2` and `order >= 1`.
    pub fn low_pass(order: usize, cutoff_hz: f64, sample_rate_hz: f64) -> Option<Butterworth> {
        let ok = order >= 1
            && sample_rate_hz.is_finite()
            && sample_rate_hz > 0.0
            && cutoff_hz > 0.0
            && cutoff_hz < 0.5 * sample_rate_hz;
        if !ok {
            return None;
        }
        let k = 2.0 * sample_rate_hz;
        let w = k * (std::f64::consts::PI * cutoff_hz / sample_rate_hz).tan();
        let n = order as f64;
        let mut sections = Vec::new();
        for i in 0..order / 2 {
            let angle = std::f64::consts::PI * (2.0 * i as f64 + n + 1.0) / (2.0 * n);
            let a = -2.0 * w * angle.cos(); // -2 Re(p) > 0
            let b = w * w; // |p|²
            let a0 = k * k + a * k + b;
            sections.push(Section {
                b: [b / a0, 2.0 * b / a0, b / a0],
                a: [(2.0 * b - 2.0 * k * k) / a0, (k * k - a * k + b) / a0],
            });
        }
        if order % 2 == 1 {
            let a0 = k + w;
            sections.push(Section {
                b: [w / a0, w / a0, 0.0],
                a: [(w - k) / a0, 0.0],
            });
        }
        Some(Butterworth {
            order,
            cutoff_hz,
            sample_rate_hz,
            sections,
        })
    }

    /// The (one-pass, causal) response at `f_hz`.
    pub fn response(&self, f_hz: f64) -> num_complex::Complex64 {
        let w = 2.0 * std::f64::consts::PI * f_hz / self.sample_rate_hz;
        self.sections
            .iter()
            .map(|s| s.response(w))
            .product::<num_complex::Complex64>()
    }

    /// One causal pass over `x`, each section started at rest on `x[0]` (see
    /// [`Section::rest_state`]).
    pub fn filter(&self, x: &[f64]) -> Vec<f64> {
        let mut y = x.to_vec();
        for s in &self.sections {
            let Some(&first) = y.first() else { break };
            let [mut s1, mut s2] = s.rest_state(first);
            for v in y.iter_mut() {
                let u = *v;
                let out = s.b[0] * u + s1;
                s1 = s.b[1] * u - s.a[0] * out + s2;
                s2 = s.b[2] * u - s.a[1] * out;
                *v = out;
            }
        }
        y
    }

    /// Samples after which the one-pass impulse response keeps less than `1e-9` of its
    /// energy: the length of the filter's memory, used to pad and to trim the edges.
    pub fn memory_samples(&self) -> usize {
        let len = (200.0 * self.sample_rate_hz / self.cutoff_hz).ceil() as usize + 16;
        let mut x = vec![0.0; len];
        x[0] = 1.0;
        let h = filter_from_rest(self, &x);
        let total: f64 = h.iter().map(|v| v * v).sum();
        let mut tail = total;
        for (i, v) in h.iter().enumerate() {
            tail -= v * v;
            if tail < 1e-9 * total {
                return i + 1;
            }
        }
        len
    }

    /// Zero-phase filtering: forward then backward (`|H|²`, no lag), the signal extended at
    /// both ends by its odd reflection about the end sample (`2 x[0] - x[pad..1]`) over
    /// `pad` samples (the filter's memory, at most `x.len() - 1`), each pass started at
    /// rest on its first sample. The same as scipy's `sosfiltfilt(sos, x, padtype="odd",
    /// padlen=pad)`.
    pub fn filtfilt(&self, x: &[f64]) -> Vec<f64> {
        let n = x.len();
        if n < 2 {
            return x.to_vec();
        }
        let pad = self.pad_samples(n);
        let mut ext = Vec::with_capacity(n + 2 * pad);
        ext.extend((1..=pad).rev().map(|i| 2.0 * x[0] - x[i]));
        ext.extend_from_slice(x);
        ext.extend((1..=pad).map(|i| 2.0 * x[n - 1] - x[n - 1 - i]));
        let mut y = self.filter(&ext);
        y.reverse();
        let mut y = self.filter(&y);
        y.reverse();
        y[pad..pad + n].to_vec()
    }

    /// The padding [`Self::filtfilt`] uses on a signal of `n` samples.
    pub fn pad_samples(&self, n: usize) -> usize {
        self.memory_samples().min(n.saturating_sub(1))
    }
}

/// One causal pass from zero states (for the impulse response).
fn filter_from_rest(f: &Butterworth, x: &[f64]) -> Vec<f64> {
    let mut y = x.to_vec();
    for s in &f.sections {
        let (mut s1, mut s2) = (0.0, 0.0);
        for v in y.iter_mut() {
            let u = *v;
            let out = s.b[0] * u + s1;
            s1 = s.b[1] * u - s.a[0] * out + s2;
            s2 = s.b[2] * u - s.a[1] * out;
            *v = out;
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// The bilinear Butterworth's magnitude in closed form:
    /// `|H|² = 1 / (1 + (tan(w/2) / tan(wc/2))^(2n))`.
    fn closed_form_mag2(order: usize, fc: f64, fs: f64, f: f64) -> f64 {
        let r = (PI * f / fs).tan() / (PI * fc / fs).tan();
        1.0 / (1.0 + r.powi(2 * order as i32))
    }

    #[test]
    fn design_matches_the_closed_form_magnitude() {
        for order in 1..=6 {
            for (fc, fs) in [(100.0, 1000.0), (7.0, 1000.0), (180.0, 400.0)] {
                let b = Butterworth::low_pass(order, fc, fs).unwrap();
                for k in 0..50 {
                    let f = (k as f64 + 0.5) / 50.0 * 0.5 * fs;
                    let got = b.response(f).norm_sqr();
                    let want = closed_form_mag2(order, fc, fs, f);
                    assert!(
                        (got - want).abs() < 1e-9 * want.max(1e-12) + 1e-14,
                        "order {order}, fc {fc}, f {f}: {got} vs {want}"
                    );
                }
                assert!(
                    (b.response(fc).norm_sqr() - 0.5).abs() < 1e-12,
                    "-3 dB at fc"
                );
            }
        }
        assert!(Butterworth::low_pass(4, 500.0, 1000.0).is_none());
        assert!(Butterworth::low_pass(0, 10.0, 1000.0).is_none());
        assert!(Butterworth::low_pass(4, -1.0, 1000.0).is_none());
    }

    /// The naive reference: the cascade multiplied out into one transfer function and run
    /// as a plain difference equation `y[k] = sum b_i x[k-i] - sum a_i y[k-i]` from zero.
    fn naive_difference_equation(b: &Butterworth, x: &[f64]) -> Vec<f64> {
        let mut num = vec![1.0];
        let mut den = vec![1.0];
        let mul = |p: &[f64], q: &[f64]| {
            let mut r = vec![0.0; p.len() + q.len() - 1];
            for (i, a) in p.iter().enumerate() {
                for (j, c) in q.iter().enumerate() {
                    r[i + j] += a * c;
                }
            }
            r
        };
        for s in &b.sections {
            num = mul(&num, &s.b);
            den = mul(&den, &[1.0, s.a[0], s.a[1]]);
        }
        let mut y = vec![0.0; x.len()];
        for k in 0..x.len() {
            let mut acc = 0.0;
            for (i, c) in num.iter().enumerate() {
                if k >= i {
                    acc += c * x[k - i];
                }
            }
            for (i, c) in den.iter().enumerate().skip(1) {
                if k >= i {
                    acc -= c * y[k - i];
                }
            }
            y[k] = acc;
        }
        y
    }

    #[test]
    fn cascade_equals_the_naive_difference_equation() {
        let b = Butterworth::low_pass(4, 37.0, 1000.0).unwrap();
        let x: Vec<f64> = (0..2000)
            .map(|k| ((k * 7919) % 1013) as f64 / 1013.0 - 0.5)
            .collect();
        let got = filter_from_rest(&b, &x);
        let want = naive_difference_equation(&b, &x);
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() < 1e-12, "{g} vs {w}");
        }
    }

    #[test]
    fn forward_backward_is_zero_phase_with_the_squared_magnitude() {
        let (fc, fs) = (50.0, 1000.0);
        let b = Butterworth::low_pass(4, fc, fs).unwrap();
        for f in [5.0, 30.0, 50.0, 70.0] {
            let n = 4000;
            let x: Vec<f64> = (0..n)
                .map(|k| (2.0 * PI * f * k as f64 / fs + 0.3).sin() + 0.7)
                .collect();
            let y = b.filtfilt(&x);
            let g = b.response(f).norm_sqr();
            // interior: the same phase, amplitude |H|², the DC passed
            for k in 1000..3000 {
                let want = g * (2.0 * PI * f * k as f64 / fs + 0.3).sin() + 0.7;
                assert!(
                    (y[k] - want).abs() < 1e-6,
                    "f {f}, k {k}: {} vs {want}",
                    y[k]
                );
            }
        }
        // a constant and a straight line pass unchanged, edges included
        let line: Vec<f64> = (0..500).map(|k| 3.0 + 0.01 * k as f64).collect();
        let y = b.filtfilt(&line);
        for (a, c) in y.iter().zip(&line) {
            assert!((a - c).abs() < 1e-6, "{a} vs {c}");
        }
        assert_eq!(b.filtfilt(&[1.5]), vec![1.5]);
        assert!(b.filtfilt(&[]).is_empty());
    }

    #[test]
    fn memory_holds_the_impulse_energy() {
        let b = Butterworth::low_pass(4, 20.0, 1000.0).unwrap();
        let m = b.memory_samples();
        // a 20 Hz filter at 1 kHz rings for a few of its periods (50 samples each)
        assert!((50..2000).contains(&m), "{m}");
        let fast = Butterworth::low_pass(4, 200.0, 1000.0).unwrap();
        assert!(fast.memory_samples() < m);
    }
}

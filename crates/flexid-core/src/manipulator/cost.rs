//! The paper's identification cost, eqs. (12) and (15): per pose `r` and FRF element
//! `(n, m)`, the `alpha`-weighted `p`-mean of the log-magnitude error over the element's
//! band `[L_b(n,m), U_b(n,m)]`,
//!
//! `V(theta) = sum_r sum_(n,m) ( sum_k alpha(n,m,k) |E_nm(w_k)|^p / sum_k alpha(n,m,k) )^(1/p)`,
//! `E_nm(w_k) = 20 log10 |G_nm(w_k, theta)| - 20 log10 |G^_nm(w_k)|` [dB].
//!
//! With the symmetric reduction (eq. (15)) the measurement is symmetrised first
//! (eq. (14): `(G^_nm + G^_mn) / 2` off the diagonal) and only the elements on and below
//! the diagonal enter; bands and weights are symmetric by construction here (one per
//! unordered pair), which the paper shows gives the same minimiser as eq. (12).
//!
//! The weights `alpha` are either the paper's (one on every line of the band) or, as an
//! option, the inverse variance of the measured log-magnitude (the identification issue's
//! lesson: a weak off-diagonal element whose lines are noise then carries little weight;
//! `../shared/design/multiaxis.md`, fact 2).

use super::ManipulatorError;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// `20 / ln 10`: dB per neper.
pub const DB_PER_NEPER: f64 = 8.685_889_638_065_035;

/// Under variance weights, a line enters only where its measured power exceeds what noise
/// alone reaches in 99 % of cases: with a circular complex Gaussian error of variance
/// `var`, `|noise|^2 / var` is exponential with mean one, `P(> x) = e^-x`, so the bound is
/// `ln 100 = 4.6`. Below it the element is not measured on that line (the weak
/// off-diagonal elements, `../shared/design/multiaxis.md` fact 2; the elements a pose's
/// symmetry makes zero): its log-magnitude is the noise floor's, which a fit would chase
/// (measured: stiffness errors 0.2 %, a damping driven to zero, on the reference robot).
pub const NOISE_ONLY_SNR: f64 = 4.605_170_185_988_092;

/// One pose's measured FRF matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseMeasurement {
    /// Frequencies [Hz].
    pub f_hz: Vec<f64>,
    /// `G^(w_k)` per line, `N x N` [rad/s per N m, motor side].
    pub g: Vec<DMatrix<Complex64>>,
    /// The variance `E|G^ - G|^2` of each element per line, where measured.
    pub var: Option<Vec<DMatrix<f64>>>,
    /// The variance of the symmetrised estimate's elements (eq. (14)) per line, where
    /// measured with the two elements' correlation; else the symmetric cost takes the two
    /// elements' errors as independent.
    pub var_sym: Option<Vec<DMatrix<f64>>>,
}

/// How the lines of an element are weighted (`alpha`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Weighting {
    /// One on every line of the band (the paper's choice in its experiments).
    #[default]
    Uniform,
    /// The inverse of the measured log-magnitude's variance,
    /// `var(20 log10 |G^|) = DB_PER_NEPER^2 var(G^) / (2 |G^|^2)` (first order, circular
    /// complex noise); needs [`PoseMeasurement::var`].
    InverseVariance,
}

/// The choices of the cost: norm, bands, weights, symmetry.
#[derive(Debug, Clone, PartialEq)]
pub struct CostSpec {
    /// The paper's `p` (2 in most of its runs), at least 1.
    pub p: f64,
    /// The band `[L_b, U_b]` [Hz] of each element `(n, m)`; `None`: every line.
    /// Only the lower triangle is read under `symmetric` (`(n, m)` with `m <= n`).
    pub band_hz: Option<DMatrix<(f64, f64)>>,
    /// The weights `alpha`.
    pub weighting: Weighting,
    /// The symmetric reduction of eq. (15).
    pub symmetric: bool,
}

impl Default for CostSpec {
    fn default() -> Self {
        CostSpec {
            p: 2.0,
            band_hz: None,
            weighting: Weighting::Uniform,
            symmetric: true,
        }
    }
}

/// One element's term of the cost at one pose: the lines of its band with their weights
/// and measured magnitudes.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    /// Pose index.
    pub pose: usize,
    /// Row (motor speed) and column (motor torque), 0-based.
    pub n: usize,
    pub m: usize,
    /// Line indices into the pose's measurement.
    pub lines: Vec<usize>,
    /// `alpha` per line of `lines`.
    pub alpha: Vec<f64>,
    /// `20 log10 |G^_nm|` per line of `lines` [dB].
    pub measured_db: Vec<f64>,
    /// `sum alpha`.
    pub alpha_sum: f64,
}

/// The cost over a set of poses, ready to evaluate.
#[derive(Debug, Clone, PartialEq)]
pub struct Cost {
    /// The spec it was built with.
    pub spec: CostSpec,
    /// Frequencies of each pose's lines [Hz].
    pub f_hz: Vec<Vec<f64>>,
    /// The terms, pose by pose, element by element.
    pub terms: Vec<Term>,
    /// Axes `N`.
    pub axes: usize,
}

impl Cost {
    /// The cost of `measured` (one per pose) under `spec`. Lines whose measured element is
    /// zero or not finite (or whose variance is not positive, with variance weights) are
    /// left out; an element with no line left has no term.
    pub fn new(measured: &[PoseMeasurement], spec: CostSpec) -> Result<Cost, ManipulatorError> {
        if !(spec.p >= 1.0 && spec.p.is_finite()) {
            return Err(ManipulatorError::NotPositive {
                what: "p - 1 (the cost's norm)",
                index: 0,
                value: spec.p - 1.0,
            });
        }
        let axes = measured
            .first()
            .map_or(0, |m| m.g.first().map_or(0, |g| g.nrows()));
        let mut terms = Vec::new();
        for (pose, meas) in measured.iter().enumerate() {
            check_pose(meas, axes)?;
            for n in 0..axes {
                let m_end = if spec.symmetric { n + 1 } else { axes };
                for m in 0..m_end {
                    if let Some(t) = term(meas, &spec, pose, n, m) {
                        terms.push(t);
                    }
                }
            }
        }
        Ok(Cost {
            spec,
            f_hz: measured.iter().map(|m| m.f_hz.clone()).collect(),
            terms,
            axes,
        })
    }

    /// One term's contribution `(sum alpha |E|^p / sum alpha)^(1/p)` from its errors `e`
    /// [dB] (in the order of its lines).
    pub fn term_value(&self, t: &Term, e: impl Iterator<Item = f64>) -> f64 {
        let p = self.spec.p;
        let s: f64 = t.alpha.iter().zip(e).map(|(a, e)| a * abs_pow(e, p)).sum();
        (s / t.alpha_sum).powf(1.0 / p)
    }

    /// `V(theta)` per pose of a model whose FRF matrices are `model[pose][line]`.
    pub fn per_pose(&self, model: &[Vec<DMatrix<Complex64>>]) -> Vec<f64> {
        let mut v = vec![0.0; self.f_hz.len()];
        for t in &self.terms {
            let e = t
                .lines
                .iter()
                .zip(&t.measured_db)
                .map(|(&k, db)| db_of(model[t.pose][k][(t.n, t.m)]) - db);
            v[t.pose] += self.term_value(t, e);
        }
        v
    }

    /// `V(theta)` of a model whose FRF matrices are `model[pose][line]`.
    pub fn value(&self, model: &[Vec<DMatrix<Complex64>>]) -> f64 {
        self.per_pose(model).iter().sum()
    }
}

/// `|e|^p`, as `e * e` for the usual `p = 2` (`powf` is a tenth of a cost pass there).
pub fn abs_pow(e: f64, p: f64) -> f64 {
    if p == 2.0 {
        e * e
    } else {
        e.abs().powf(p)
    }
}

/// `20 log10 |g|` [dB]: `10 log10 |g|^2` (no `hypot`: a tenth of a cost pass), or from
/// `|g|` where `|g|^2` would leave the range of `f64`.
pub fn db_of(g: Complex64) -> f64 {
    let p = g.norm_sqr();
    if p > 1e-300 && p < 1e300 {
        0.5 * DB_PER_NEPER * p.ln()
    } else {
        DB_PER_NEPER * g.norm().ln()
    }
}

/// The measurement of one pose checked: square `axes x axes` matrices, one per
/// frequency, variances alike.
fn check_pose(meas: &PoseMeasurement, axes: usize) -> Result<(), ManipulatorError> {
    if meas.g.len() != meas.f_hz.len() {
        return Err(ManipulatorError::Length {
            what: "measured FRF matrices",
            expected: meas.f_hz.len(),
            got: meas.g.len(),
        });
    }
    let mats = meas.g.iter().map(|g| (g.nrows(), g.ncols()));
    let vars = meas.var.iter().flatten().map(|v| (v.nrows(), v.ncols()));
    for (rows, cols) in mats.chain(vars) {
        if rows != axes || cols != axes {
            return Err(ManipulatorError::Shape {
                what: "measured FRF matrix",
                rows,
                cols,
                expected: axes,
            });
        }
    }
    if let Some(v) = &meas.var {
        if v.len() != meas.f_hz.len() {
            return Err(ManipulatorError::Length {
                what: "measured variances",
                expected: meas.f_hz.len(),
                got: v.len(),
            });
        }
    }
    Ok(())
}

/// The measured element `(n, m)` at line `k` (symmetrised under the spec) and its
/// variance.
fn element(
    meas: &PoseMeasurement,
    spec: &CostSpec,
    k: usize,
    n: usize,
    m: usize,
) -> (Complex64, Option<f64>) {
    let g = &meas.g[k];
    let var = meas.var.as_ref().map(|v| &v[k]);
    if spec.symmetric && n != m {
        // eq. (14); without a measured variance of it, the two estimates' errors taken as
        // independent
        let var_sym = match &meas.var_sym {
            Some(v) => Some(v[k][(n, m)]),
            None => var.map(|v| (v[(n, m)] + v[(m, n)]) * 0.25),
        };
        ((g[(n, m)] + g[(m, n)]) * 0.5, var_sym)
    } else {
        (g[(n, m)], var.map(|v| v[(n, m)]))
    }
}

/// The term of element `(n, m)` of pose `pose`, `None` when no line is usable.
fn term(meas: &PoseMeasurement, spec: &CostSpec, pose: usize, n: usize, m: usize) -> Option<Term> {
    let (lo, hi) = spec
        .band_hz
        .as_ref()
        .map_or((f64::NEG_INFINITY, f64::INFINITY), |b| b[(n, m)]);
    let mut t = Term {
        pose,
        n,
        m,
        lines: Vec::new(),
        alpha: Vec::new(),
        measured_db: Vec::new(),
        alpha_sum: 0.0,
    };
    for (k, &f) in meas.f_hz.iter().enumerate() {
        if !(f >= lo && f <= hi) {
            continue;
        }
        let (g, var) = element(meas, spec, k, n, m);
        let mag2 = g.norm_sqr();
        if !(mag2 > 0.0 && mag2.is_finite()) {
            continue;
        }
        let alpha = match spec.weighting {
            Weighting::Uniform => 1.0,
            Weighting::InverseVariance => match var {
                // a line whose magnitude the noise alone reaches is not a measured
                // magnitude: its dB value is biased and its first-order variance wrong
                Some(v) if v > 0.0 && v.is_finite() && mag2 < NOISE_ONLY_SNR * v => continue,
                Some(v) if v > 0.0 && v.is_finite() => {
                    1.0 / (DB_PER_NEPER * DB_PER_NEPER * v / (2.0 * mag2))
                }
                _ => continue,
            },
        };
        t.lines.push(k);
        t.alpha.push(alpha);
        t.measured_db.push(db_of(g));
        t.alpha_sum += alpha;
    }
    (!t.lines.is_empty()).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measurement(values: &[[f64; 4]]) -> PoseMeasurement {
        PoseMeasurement {
            f_hz: (0..values.len()).map(|k| 10.0 * (k + 1) as f64).collect(),
            g: values
                .iter()
                .map(|v| DMatrix::from_row_slice(2, 2, &v.map(|x| Complex64::new(x, 0.0))))
                .collect(),
            var: None,
            var_sym: None,
        }
    }

    /// The cost written out by hand for a 2 x 2 case: the symmetric reduction of eq. (15)
    /// and the full sum of eq. (12) on a symmetric measurement give the same minimiser
    /// (eq. (12) counts each off-diagonal element twice).
    #[test]
    fn the_cost_is_the_papers_sum() {
        let meas = measurement(&[[1.0, 0.1, 0.1, 2.0], [0.5, 0.2, 0.2, 1.0]]);
        // the model: every element 10 % (0.83 dB) above the measurement, element (1,0) 1 %
        let model: Vec<DMatrix<Complex64>> = meas
            .g
            .iter()
            .map(|g| {
                let mut m = g * Complex64::new(1.1, 0.0);
                m[(1, 0)] = g[(1, 0)] * 1.01;
                m[(0, 1)] = g[(0, 1)] * 1.01;
                m
            })
            .collect();
        let e_diag = 20.0 * 1.1f64.log10();
        let e_off = 20.0 * 1.01f64.log10();
        let sym = Cost::new(std::slice::from_ref(&meas), CostSpec::default()).unwrap();
        assert_eq!(sym.terms.len(), 3);
        let v = sym.value(std::slice::from_ref(&model));
        assert!((v - (2.0 * e_diag + e_off)).abs() < 1e-12, "{v}");
        let full = Cost::new(
            std::slice::from_ref(&meas),
            CostSpec {
                symmetric: false,
                ..CostSpec::default()
            },
        )
        .unwrap();
        let v = full.value(std::slice::from_ref(&model));
        assert!((v - (2.0 * e_diag + 2.0 * e_off)).abs() < 1e-12, "{v}");
        // p = 1: the weighted mean of |E|; a band that keeps the first line only
        let mut band = DMatrix::from_element(2, 2, (0.0, 1e9));
        band[(1, 0)] = (0.0, 15.0);
        let p1 = Cost::new(
            std::slice::from_ref(&meas),
            CostSpec {
                p: 1.0,
                band_hz: Some(band),
                ..CostSpec::default()
            },
        )
        .unwrap();
        assert_eq!(p1.terms[1].lines, [0]);
        let v = p1.value(std::slice::from_ref(&model));
        assert!((v - (2.0 * e_diag + e_off)).abs() < 1e-12, "{v}");
    }

    /// Variance weights: `alpha = 1 / var(dB)`; a line with twice the relative spread
    /// weighs a quarter.
    #[test]
    fn variance_weights_follow_the_log_magnitude_variance() {
        let mut meas = measurement(&[[1.0, 0.1, 0.1, 2.0], [1.0, 0.1, 0.1, 2.0]]);
        meas.var = Some(vec![
            DMatrix::from_element(2, 2, 1e-4),
            DMatrix::from_element(2, 2, 4e-4),
        ]);
        let c = Cost::new(
            &[meas],
            CostSpec {
                weighting: Weighting::InverseVariance,
                ..CostSpec::default()
            },
        )
        .unwrap();
        let t = &c.terms[0];
        assert!((t.alpha[0] / t.alpha[1] - 4.0).abs() < 1e-12);
        // sigma of the magnitude of a unit element with var 1e-4: 8.69 * 0.00707 dB
        let sigma_db = (1.0 / t.alpha[0]).sqrt();
        assert!((sigma_db - DB_PER_NEPER * (0.5e-4f64).sqrt()).abs() < 1e-12);
        // a line the noise alone reaches (|G|^2 / var below ln 100) is left out: the
        // symmetrised element (1,0), 0.1 against a variance (1e-2 + 1e-2) / 4 (power ratio
        // 2), on the second line only
        let mut weak = measurement(&[[1.0, 0.1, 0.1, 2.0], [1.0, 0.1, 0.1, 2.0]]);
        let mut second = DMatrix::from_element(2, 2, 1e-4);
        second[(1, 0)] = 1e-2;
        second[(0, 1)] = 1e-2;
        weak.var = Some(vec![DMatrix::from_element(2, 2, 1e-4), second]);
        let c = Cost::new(
            &[weak],
            CostSpec {
                weighting: Weighting::InverseVariance,
                ..CostSpec::default()
            },
        )
        .unwrap();
        let off = c.terms.iter().find(|t| (t.n, t.m) == (1, 0)).unwrap();
        assert_eq!(off.lines, [0]);
        let diag = c.terms.iter().find(|t| (t.n, t.m) == (1, 1)).unwrap();
        assert_eq!(diag.lines, [0, 1]);
        // without variances the inverse-variance cost has no line to use
        let none = Cost::new(
            &[measurement(&[[1.0, 0.1, 0.1, 2.0]])],
            CostSpec {
                weighting: Weighting::InverseVariance,
                ..CostSpec::default()
            },
        )
        .unwrap();
        assert!(none.terms.is_empty());
    }
}

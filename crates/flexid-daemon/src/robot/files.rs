//! The files of a robot job and their JSON forms: the measured FRF matrix of a pose
//! (`frf_matrix.json`: every element's complex value and variance per line, and the
//! magnitudes and phases a page plots), the identification (`identification.json`), the
//! job's status (`job.json`). Written atomically; read back to identify from sweeps of an
//! earlier run.

use flexid_core::frf::MimoFrf;
use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// Files of one job directory.
pub const JOB_JSON: &str = "job.json";
pub const FRF_MATRIX_JSON: &str = "frf_matrix.json";
pub const BODE_MATRIX_SVG: &str = "bode_matrix.svg";
pub const IDENTIFICATION_JSON: &str = "identification.json";

/// An FRF matrix per line in plain arrays: `[line][output][input]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MatrixLines {
    /// Real and imaginary parts [rad/s per N m].
    pub re: Vec<Vec<Vec<f64>>>,
    pub im: Vec<Vec<Vec<f64>>>,
}

impl MatrixLines {
    /// From per-line matrices.
    pub fn of(g: &[DMatrix<Complex64>]) -> Self {
        let part = |f: fn(&Complex64) -> f64| {
            g.iter()
                .map(|m| {
                    (0..m.nrows())
                        .map(|i| (0..m.ncols()).map(|j| f(&m[(i, j)])).collect())
                        .collect()
                })
                .collect()
        };
        MatrixLines {
            re: part(|c| c.re),
            im: part(|c| c.im),
        }
    }

    /// Back to per-line matrices (`None` when the arrays are ragged).
    pub fn matrices(&self) -> Option<Vec<DMatrix<Complex64>>> {
        if self.re.len() != self.im.len() {
            return None;
        }
        self.re
            .iter()
            .zip(&self.im)
            .map(|(re, im)| {
                let n = re.len();
                if im.len() != n || re.iter().chain(im).any(|r| r.len() != n) {
                    return None;
                }
                Some(DMatrix::from_fn(n, n, |i, j| {
                    Complex64::new(re[i][j], im[i][j])
                }))
            })
            .collect()
    }

    /// `|G|` [dB re 1 (rad/s)/(N m)] and phase [deg], `[output][input][line]` (what a
    /// page plots).
    pub fn bode(&self) -> (Vec<Vec<Vec<f64>>>, Vec<Vec<Vec<f64>>>) {
        let n = self.re.first().map_or(0, Vec::len);
        let lines = self.re.len();
        let at = |i: usize, j: usize, k: usize| Complex64::new(self.re[k][i][j], self.im[k][i][j]);
        let mag = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| (0..lines).map(|k| db(at(i, j, k).norm())).collect())
                    .collect()
            })
            .collect();
        let phase = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| (0..lines).map(|k| at(i, j, k).arg().to_degrees()).collect())
                    .collect()
            })
            .collect();
        (mag, phase)
    }
}

/// `20 log10 x`, floored at -400 dB (no infinity in JSON).
fn db(x: f64) -> f64 {
    (20.0 * x.log10()).max(-400.0)
}

/// Variances per line in plain arrays: `[line][output][input]`.
fn var_lines(v: &[DMatrix<f64>]) -> Vec<Vec<Vec<f64>>> {
    v.iter()
        .map(|m| {
            (0..m.nrows())
                .map(|i| (0..m.ncols()).map(|j| finite_or_max(m[(i, j)])).collect())
                .collect()
        })
        .collect()
}

fn finite_or_max(x: f64) -> f64 {
    if x.is_finite() {
        x
    } else {
        f64::MAX
    }
}

fn var_matrices(v: &[Vec<Vec<f64>>]) -> Vec<DMatrix<f64>> {
    v.iter()
        .map(|m| {
            let n = m.len();
            DMatrix::from_fn(n, n, |i, j| m[i].get(j).copied().unwrap_or(f64::INFINITY))
        })
        .collect()
}

/// `frf_matrix.json`: a pose's measured FRF matrix (motor torques to motor speeds).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrfMatrixFile {
    pub robot: String,
    pub pose: String,
    /// The pose's joint angles [deg].
    pub q_deg: Vec<f64>,
    /// The drives' node ids, axis by axis.
    pub nodes: Vec<u8>,
    pub sample_rate_hz: f64,
    /// The excited lines [Hz].
    pub freq_hz: Vec<f64>,
    /// The estimate, its variance per element and the symmetrised estimate's variance.
    pub g: MatrixLines,
    pub var: Vec<Vec<Vec<f64>>>,
    pub var_sym: Vec<Vec<Vec<f64>>>,
    /// `[output][input][line]`: |G| [dB] and phase [deg] of the estimate, for plotting.
    pub magnitude_db: Vec<Vec<Vec<f64>>>,
    pub phase_deg: Vec<Vec<Vec<f64>>>,
}

impl FrfMatrixFile {
    /// The file of `frf` measured at pose `pose` (`q_deg`) of `robot` through `nodes`.
    pub fn new(robot: &str, pose: &str, q_deg: &[f64], nodes: &[u8], frf: &MimoFrf) -> Self {
        let g = MatrixLines::of(&frf.g);
        let (magnitude_db, phase_deg) = g.bode();
        FrfMatrixFile {
            robot: robot.to_string(),
            pose: pose.to_string(),
            q_deg: q_deg.to_vec(),
            nodes: nodes.to_vec(),
            sample_rate_hz: frf.sample_rate_hz,
            freq_hz: frf.freq_hz.clone(),
            g,
            var: var_lines(&frf.var),
            var_sym: var_lines(&frf.var_sym),
            magnitude_db,
            phase_deg,
        }
    }

    /// The measurement the identification compares with.
    pub fn measurement(&self) -> Option<flexid_core::manipulator::PoseMeasurement> {
        Some(flexid_core::manipulator::PoseMeasurement {
            f_hz: self.freq_hz.clone(),
            g: self.g.matrices()?,
            var: Some(var_matrices(&self.var)),
            var_sym: Some(var_matrices(&self.var_sym)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrices_round_trip_through_json() {
        let g = vec![
            DMatrix::from_fn(2, 2, |i, j| Complex64::new(i as f64 + 0.5, j as f64 - 2.0)),
            DMatrix::from_fn(2, 2, |i, j| Complex64::new(-(i as f64), 3.0 * j as f64)),
        ];
        let m = MatrixLines::of(&g);
        let text = serde_json::to_string(&m).unwrap();
        let back: MatrixLines = serde_json::from_str(&text).unwrap();
        assert_eq!(back.matrices().unwrap(), g);
        let (mag, phase) = m.bode();
        assert!((mag[0][1][0] - db(g[0][(0, 1)].norm())).abs() < 1e-12);
        assert!((phase[1][0][1] - g[1][(1, 0)].arg().to_degrees()).abs() < 1e-12);
        // a zero element is -400 dB, not -inf
        assert_eq!(mag[0][0][1], -400.0);
    }
}

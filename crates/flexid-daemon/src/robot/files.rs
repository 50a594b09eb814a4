//! The files of a robot job and their JSON forms: the measured FRF matrix of a pose
//! (`frf_matrix.json`: every element's complex value and variance per line, and the
//! magnitudes and phases a page plots), the identification (`identification.json`), the
//! job's status (`job.json`). Written atomically; read back to identify from sweeps of an
//! earlier run.

use std::path::Path;

use flexid_core::frf::MimoFrf;
use flexid_core::manipulator::identify::{model_frf, FrfForm};
use flexid_core::manipulator::{
    identify, Cost, CostSpec, Flexibilities, FlexibleRobot, IdentifyOptions, Weighting,
};
use flexid_files::plot::{bode_matrix_svg, BodeMatrix};
use flexid_sweep::MultiSweepOutcome;
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

/// Writes `value` as JSON to `path` atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), String> {
    let text = serde_json::to_vec(value).map_err(|e| e.to_string())?;
    flexid_files::recording::write_bytes_atomic(path, &text)
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// Writes a measured pose into `dir`: `frf_matrix.json` and `bode_matrix.svg`. Returns a
/// one-line summary of the measurement.
pub fn write_pose_files(
    dir: &Path,
    robot: &str,
    pose: &str,
    q_deg: &[f64],
    nodes: &[u8],
    frf: &MimoFrf,
    outcome: &MultiSweepOutcome,
) -> Result<String, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let file = FrfMatrixFile::new(robot, pose, q_deg, nodes, frf);
    write_json(&dir.join(FRF_MATRIX_JSON), &file)?;
    let title = format!("{robot} at pose {pose}: FRF matrix, motor torques to motor speeds");
    let svg = bode_matrix_svg(&BodeMatrix {
        title: &title,
        f_hz: &frf.freq_hz,
        measured: &frf.g,
        var: Some(&frf.var),
        model: None,
    });
    let svg_path = dir.join(BODE_MATRIX_SVG);
    flexid_files::recording::write_bytes_atomic(&svg_path, svg.as_bytes())
        .map_err(|e| format!("{}: {e}", svg_path.display()))?;
    let lost: u64 = outcome.counters.iter().map(|c| c.lost).sum();
    Ok(format!(
        "{} cycles on {} axes, {} lines of {:.0}-{:.0} Hz, {lost} feedback messages lost",
        outcome.record.len(),
        nodes.len(),
        frf.freq_hz.len(),
        frf.freq_hz.first().copied().unwrap_or(0.0),
        frf.freq_hz.last().copied().unwrap_or(0.0)
    ))
}

/// Identifies `robot`'s flexibilities from measured poses (`(sweep id, file)`): the
/// paper's cost with inverse-variance weights on the sampled model at `fs_hz`, `starts`
/// starts from the file's values. Returns `identification.json`'s document (every
/// parameter with its file value, uncertainty and identifiability, every start's cost,
/// V per pose, the model's magnitudes and phases at each pose) and a one-line summary.
pub fn identify_files(
    robot: &FlexibleRobot,
    name: &str,
    files: &[(String, FrfMatrixFile)],
    starts: usize,
    fs_hz: f64,
) -> Result<(serde_json::Value, String), String> {
    let mut poses = Vec::new();
    let mut meas = Vec::new();
    for (_, f) in files {
        let q: Vec<f64> = f.q_deg.iter().map(|d| d.to_radians()).collect();
        poses.push(
            robot
                .pose(&q)
                .map_err(|e| format!("pose {}: {e}", f.pose))?,
        );
        meas.push(
            f.measurement()
                .ok_or_else(|| format!("pose {}: a ragged FRF matrix", f.pose))?,
        );
    }
    let spec = CostSpec {
        weighting: Weighting::InverseVariance,
        ..CostSpec::default()
    };
    let cost = Cost::new(&meas, spec).map_err(|e| e.to_string())?;
    let form = FrfForm::Sampled { fs_hz };
    let result = identify(
        &poses,
        &cost,
        &robot.nominal,
        &IdentifyOptions {
            starts,
            form,
            ..IdentifyOptions::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let model = model_frf(&poses, &cost, &result.best, form).map_err(|e| e.to_string())?;
    let names = robot.parameter_names();
    let params = parameters_json(robot, &result);
    let models: Vec<_> = files
        .iter()
        .zip(&model)
        .zip(&result.cost_per_pose)
        .map(|(((s, f), g), v)| {
            let (mag, phase) = MatrixLines::of(g).bode();
            serde_json::json!({
                "sweep": s, "pose": f.pose, "v_db": v,
                "freq_hz": f.freq_hz, "magnitude_db": mag, "phase_deg": phase,
            })
        })
        .collect();
    let good = result.good.len();
    let doc = serde_json::json!({
        "robot": name,
        "sweeps": files.iter().map(|(s, _)| s).collect::<Vec<_>>(),
        "starts": result.starts.iter().map(|s| s.cost).collect::<Vec<_>>(),
        "good_starts": good,
        "cost_db": result.cost,
        "cost_per_pose_db": result.cost_per_pose,
        "form": "sampled",
        "parameters": params,
        "models": models,
    });
    let summary = format!(
        "{} parameters from {} poses; V {:.4} dB; {good} of {starts} starts reached the best cost",
        names.len(),
        files.len(),
        result.cost
    );
    Ok((doc, summary))
}

/// Every identified parameter as JSON: `name`, `value`, the file's value (`nominal`),
/// `unit`, `std_rel` (the standard uncertainty of its logarithm; null where the data carry
/// none) and `identifiable`.
pub fn parameters_json(
    robot: &FlexibleRobot,
    result: &flexid_core::manipulator::Identification,
) -> Vec<serde_json::Value> {
    let flat = |t: &Flexibilities| -> Vec<f64> {
        t.stiffness_nm_per_rad
            .iter()
            .chain(&t.damping_nms_per_rad)
            .copied()
            .collect()
    };
    let (values, nominal) = (flat(&result.best), flat(&robot.nominal));
    let ns = robot.springs.len();
    robot
        .parameter_names()
        .iter()
        .enumerate()
        .map(|(j, n)| {
            let std = result
                .std_ln
                .as_ref()
                .map(|s| s[j])
                .filter(|s| s.is_finite());
            serde_json::json!({
                "name": n,
                "value": values[j],
                "nominal": nominal[j],
                "unit": if j < ns { "N m/rad" } else { "N m s/rad" },
                "std_rel": std,
                "identifiable": result.identifiable(j),
            })
        })
        .collect()
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

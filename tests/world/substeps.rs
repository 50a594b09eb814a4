//! How many RK4 sub-steps per sample the world's simulator needs: from the stiffest
//! dynamics of a plant (see [`super::simulator`] for the bounds and why).

use super::plant::{Law, Plant};

fn rad_s(hz: f64) -> f64 {
    2.0 * std::f64::consts::PI * hz
}

/// Peak excursions expected in a run, to bound the stiffness that the nonlinear springs
/// reach (from the linear response, see `super::analytic::peaks`).
#[derive(Debug, Clone, Default)]
pub struct Peaks {
    /// Per coupling [rad].
    pub deflection_rad: Vec<f64>,
    /// Per body [rad].
    pub position_rad: Vec<f64>,
}

/// The stiffest dynamics of `plant`: the highest eigenfrequency [rad/s] (bodies with every
/// spring at its largest stiffness within `peaks`, and the filters' and
/// sensor's own frequencies) and the fastest damping rate [1/s].
pub fn stiffest(plant: &Plant, peaks: &Peaks) -> (f64, f64) {
    let nb = plant.bodies();
    let mut k = vec![vec![0.0; nb]; nb];
    let mut c = vec![0.0; nb];
    for (i, cp) in plant.couplings.iter().enumerate() {
        let x = peaks.deflection_rad.get(i).copied().unwrap_or(0.0);
        let s = cp.stiffness_nm_per_rad
            * match cp.law {
                Law::Hardening { x_ref_rad } => 1.0 + 3.0 * (x / x_ref_rad).powi(2),
                _ => 1.0,
            };
        k[i][i] += s;
        k[i + 1][i + 1] += s;
        k[i][i + 1] -= s;
        k[i + 1][i] -= s;
        c[i] += cp.damping_nms_per_rad;
        c[i + 1] += cp.damping_nms_per_rad;
    }
    c[0] += plant.motor_viscous_nms_per_rad;
    if let Some(f) = &plant.friction {
        // the regularisation's slope at zero speed, Stribeck peak included
        c[0] += f.static_nm.max(f.coulomb_nm) / f.regularisation_rad_s;
    }
    if let Some(g) = &plant.gravity {
        k[g.body][g.body] += g.m_g_l_nm;
        c[g.body] += g.bearing_damping_nms_per_rad;
    }
    if let Some(g) = &plant.ground_cubic {
        let q = peaks.position_rad.get(g.body).copied().unwrap_or(0.0);
        k[g.body][g.body] += 3.0 * g.cubic_nm_per_rad3 * q * q;
    }
    if let Some(cg) = &plant.cogging {
        k[0][0] += cg.amplitude_nm * cg.periods_per_rev;
    }
    let j = &plant.inertia_kgm2;
    let a: Vec<Vec<f64>> = (0..nb)
        .map(|r| (0..nb).map(|s| k[r][s] / (j[r] * j[s]).sqrt()).collect())
        .collect();
    let lambda = jacobi_eigenvalues(a).into_iter().fold(0.0, f64::max);
    let mut w = lambda.max(0.0).sqrt();
    // dampers: Gershgorin bound on M^-1 C (each damper counts twice, on both bodies)
    let mut rate = (0..nb).map(|i| 2.0 * c[i] / j[i]).fold(0.0, f64::max);
    let mut filter = |hz: f64, zeta: f64| {
        w = w.max(rad_s(hz));
        rate = rate.max(2.0 * zeta * rad_s(hz));
    };
    if let Some(n) = &plant.drive.notch {
        filter(n.centre_hz, n.pole_damping_ratio.max(n.zero_damping_ratio));
    }
    if let Some(l) = &plant.drive.current_loop {
        filter(l.bandwidth_hz, l.damping_ratio.max(0.5));
    }
    if let Some(l) = &plant.sensor.lowpass {
        filter(l.bandwidth_hz, l.damping_ratio.max(0.5));
    }
    if let Some(s) = &plant.sensor.shaft {
        filter(s.frequency_hz, s.damping_ratio);
    }
    (w, rate)
}

/// RK4 sub-steps per sample at `fs_hz` for `plant`: `w_max h <= 0.1` and `rate h <= 0.2`
/// ([`stiffest`]), at least 4.
pub fn substeps(plant: &Plant, fs_hz: f64, peaks: &Peaks) -> usize {
    let (w, rate) = stiffest(plant, peaks);
    let ts = 1.0 / fs_hz;
    ((w * ts / 0.1).ceil() as usize)
        .max((rate * ts / 0.2).ceil() as usize)
        .max(4)
}

/// Eigenvalues of a small symmetric matrix (cyclic Jacobi rotations).
#[allow(clippy::needless_range_loop)]
pub fn jacobi_eigenvalues(mut a: Vec<Vec<f64>>) -> Vec<f64> {
    let n = a.len();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        let scale: f64 = (0..n).map(|i| a[i][i] * a[i][i]).sum::<f64>().max(1e-300);
        if off <= 1e-24 * scale {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                if a[p][q].abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let cs = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * cs;
                for k in 0..n {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = cs * akp - sn * akq;
                    a[k][q] = sn * akp + cs * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = cs * apk - sn * aqk;
                    a[q][k] = sn * apk + cs * aqk;
                }
            }
        }
    }
    (0..n).map(|i| a[i][i]).collect()
}

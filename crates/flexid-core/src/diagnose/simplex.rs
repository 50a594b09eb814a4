//! Derivative-free minimisation (Nelder-Mead simplex) for the parameter searches whose cost
//! is a simulation: piecewise flat at small steps (backlash contact switching), so finite
//! differences and Levenberg-Marquardt do not move.

/// Result of [`minimise`].
#[derive(Debug, Clone)]
pub struct Simplex {
    /// Best point found.
    pub x: Vec<f64>,
    /// Its cost.
    pub f: f64,
    /// Cost evaluations spent.
    pub evals: usize,
}

/// Minimise `f` from `x0` with initial steps `step` (one simplex vertex per coordinate), at
/// most `max_evals` evaluations (including the `n + 1` of the start simplex). Non-finite
/// costs count as worse than any finite one. Standard coefficients (reflection 1, expansion
/// 2, contraction 1/2, shrink 1/2).
pub fn minimise(
    x0: &[f64],
    step: &[f64],
    max_evals: usize,
    mut f: impl FnMut(&[f64]) -> f64,
) -> Simplex {
    let n = x0.len();
    let mut evals = 0usize;
    let mut eval = |x: &[f64], evals: &mut usize| {
        *evals += 1;
        let v = f(x);
        if v.is_finite() {
            v
        } else {
            f64::INFINITY
        }
    };
    let mut pts: Vec<(Vec<f64>, f64)> = Vec::with_capacity(n + 1);
    let f0 = eval(x0, &mut evals);
    pts.push((x0.to_vec(), f0));
    for i in 0..n {
        let mut x = x0.to_vec();
        x[i] += step[i];
        let v = eval(&x, &mut evals);
        pts.push((x, v));
    }
    let mut centroid = vec![0.0; n];
    let at = |c: &[f64], w: &[f64], t: f64| -> Vec<f64> {
        c.iter().zip(w).map(|(c, w)| c + t * (w - c)).collect()
    };
    while evals < max_evals {
        pts.sort_by(|a, b| a.1.total_cmp(&b.1));
        centroid.iter_mut().for_each(|c| *c = 0.0);
        for (x, _) in &pts[..n] {
            for (c, v) in centroid.iter_mut().zip(x) {
                *c += v / n as f64;
            }
        }
        let worst = pts[n].clone();
        let xr = at(&centroid, &worst.0, -1.0);
        let fr = eval(&xr, &mut evals);
        if fr < pts[0].1 {
            let xe = at(&centroid, &worst.0, -2.0);
            let fe = if evals < max_evals {
                eval(&xe, &mut evals)
            } else {
                f64::INFINITY
            };
            pts[n] = if fe < fr { (xe, fe) } else { (xr, fr) };
            continue;
        }
        if fr < pts[n - 1].1 {
            pts[n] = (xr, fr);
            continue;
        }
        if evals >= max_evals {
            break;
        }
        // contraction: outside when the reflection improved on the worst, else inside
        let (xc, fc) = if fr < worst.1 {
            let xc = at(&centroid, &worst.0, -0.5);
            let v = eval(&xc, &mut evals);
            (xc, v)
        } else {
            let xc = at(&centroid, &worst.0, 0.5);
            let v = eval(&xc, &mut evals);
            (xc, v)
        };
        if fc < worst.1.min(fr) {
            pts[n] = (xc, fc);
            continue;
        }
        // shrink towards the best
        let best = pts[0].0.clone();
        for p in pts.iter_mut().skip(1) {
            if evals >= max_evals {
                break;
            }
            p.0 = at(&best, &p.0, 0.5);
            p.1 = eval(&p.0, &mut evals);
        }
    }
    pts.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (x, f) = pts.swap_remove(0);
    Simplex { x, f, evals }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Rosenbrock valley from (-1.2, 1): the minimum (1, 1) to 1e-3 within the budget,
    /// and never more evaluations than the budget; the naive reference is a grid scan of
    /// the same function, whose best point the simplex must beat.
    #[test]
    fn finds_the_rosenbrock_minimum_within_its_budget() {
        let rosen = |x: &[f64]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2);
        let r = minimise(&[-1.2, 1.0], &[0.5, 0.5], 400, rosen);
        assert!(r.evals <= 400, "{} evaluations", r.evals);
        assert!(
            (r.x[0] - 1.0).abs() < 1e-3 && (r.x[1] - 1.0).abs() < 1e-3,
            "{:?} after {} evaluations",
            r.x,
            r.evals
        );
        let mut grid_best = f64::INFINITY;
        for i in 0..=40 {
            for j in 0..=40 {
                let x = [-2.05 + 0.1 * i as f64, -2.05 + 0.1 * j as f64];
                grid_best = grid_best.min(rosen(&x));
            }
        }
        assert!(r.f < grid_best, "{} vs grid {}", r.f, grid_best);
    }

    /// Non-finite costs (an unstable simulation) are avoided, not followed.
    #[test]
    fn steps_around_non_finite_costs() {
        let f = |x: &[f64]| {
            if x[0] > 2.0 {
                f64::NAN
            } else {
                (x[0] - 1.5).powi(2) + x[1] * x[1]
            }
        };
        let r = minimise(&[0.0, 1.0], &[1.0, 1.0], 200, f);
        assert!(
            (r.x[0] - 1.5).abs() < 1e-3 && r.x[1].abs() < 1e-3,
            "{:?}",
            r.x
        );
    }
}

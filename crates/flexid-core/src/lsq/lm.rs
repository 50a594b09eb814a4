//! flexid's Levenberg-Marquardt solver on the normal equations, for every least-squares
//! fit of the project: the chain fit of the identification ([`crate::identify`], whose
//! `ChainProblem` accumulates the normal equations analytically) and the diagnosis's joint
//! refits ([`super::residuals`], normal equations from a residual closure by forward
//! differences).
//!
//! Why the normal equations (Marquardt's scaled damping `(A + lambda D^2) delta = -g`,
//! `A = J^T J`, `g = J^T r`, `D^2 = diag A` with Moré's running maximum) solved by a Cholesky
//! factorisation of the `P x P` matrix, and not Moré's QR-based trust region (MINPACK,
//! the `levenberg-marquardt` crate): the chain fit has `2 x 3200` residuals and `P = 7`
//! parameters. `A` and `g` are accumulated while the residuals and the analytic Jacobian
//! rows are computed (the identification's `ChainProblem`), `N P^2` multiply-adds that stream
//! through the lines once; the `N x P` Jacobian is never stored and its pivoted QR
//! (`2 N P^2` flops plus the copy, about half of the former fit time) disappears. Each
//! damping change then costs a `7 x 7` Cholesky, nothing proportional to `N`. The price of
//! the normal equations, the squared condition number, does not bite here: the parameters
//! are logarithms (all of order one in scale), the scaling by `diag A` removes the
//! remaining column scale, and the fit's covariance is `A^-1` anyway; a matrix that is not
//! numerically positive definite simply raises the damping. The damping update is
//! Nielsen's (smooth decrease by the gain ratio, doubling increase), which needs no
//! trust-region radius bookkeeping.
//!
//! A trial step is evaluated by its cost alone ([`NormalEquations::cost`]); the normal equations
//! are accumulated only when the step is accepted, from the per-line quantities the cost
//! pass left behind ([`NormalEquations::normal_after_cost`]), so that a rejected step costs no
//! Jacobian pass.
//!
//! All buffers live in [`LmWorkspace`], planned once per fit: an iteration allocates
//! nothing in the solver and the line pass.

/// A least-squares problem as the solver sees it: the cost `sum r^2` at the current
/// parameters and the normal equations `J^T J`, `J^T r` there. `Scratch` holds what a cost
/// pass leaves for the normal-equation pass after it (planned once per fit).
pub trait NormalEquations {
    /// Per-evaluation buffers.
    type Scratch;
    /// Buffers sized for this problem.
    fn scratch(&self) -> Self::Scratch;
    /// Move to the parameters `theta`.
    fn set_theta(&mut self, theta: &[f64]);
    /// The cost at the current parameters; `None` where the model is invalid or the cost
    /// is not finite.
    fn cost(&mut self, s: &mut Self::Scratch) -> Option<f64>;
    /// The normal equations (`jtj` `P x P` row-major, `jtr`) at the parameters of the last
    /// [`NormalEquations::cost`]; `false` where they are not finite.
    fn normal_after_cost(
        &mut self,
        s: &mut Self::Scratch,
        jtj: &mut [f64],
        jtr: &mut [f64],
    ) -> bool;
    /// The cost and the normal equations.
    fn normal_equations(
        &mut self,
        s: &mut Self::Scratch,
        jtj: &mut [f64],
        jtr: &mut [f64],
    ) -> Option<f64> {
        let cost = self.cost(s)?;
        self.normal_after_cost(s, jtj, jtr).then_some(cost)
    }
}

/// How the damping `lambda` of [`minimize`] moves and what scales it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Damping {
    /// Nielsen's smooth update from the gain ratio (doubling on a rejected step), scaled by
    /// Moré's running maximum of `diag(J^T J)`; stops on `ftol`, `xtol` and `gtol`. The
    /// chain fit's.
    #[default]
    Nielsen,
    /// Marquardt's schedule: `lambda` times 0.3 after an accepted step and 10 after a
    /// rejected one, scaled by the current `diag(J^T J)`; stops when an accepted step
    /// lowers the cost by less than `ftol` of it, after 8 rejected steps in a row, or after
    /// `max_steps` accepted steps. The diagnosis's refits.
    Marquardt {
        /// Accepted steps (each a new Jacobian) at most.
        max_steps: usize,
    },
}

/// Convergence tolerances and budget of [`minimize`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    /// Stop when both the actual and the predicted relative cost reduction of a step are
    /// below this.
    pub ftol: f64,
    /// Stop when the scaled step is below this relative to the scaled parameters.
    pub xtol: f64,
    /// Stop when the cosine between the residual and every Jacobian column is below this.
    pub gtol: f64,
    /// Maximum number of model evaluations (each one residuals and normal equations).
    pub max_evals: usize,
    /// The damping schedule.
    pub damping: Damping,
}

/// Result of [`minimize`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmOutcome {
    /// Cost `sum r^2` at the end.
    pub cost: f64,
    /// Model evaluations used.
    pub evaluations: usize,
    /// Whether a tolerance was met (otherwise the budget ran out or the damping blew up).
    pub converged: bool,
    /// Whether the caller's stop condition ended the run ([`minimize_until`]).
    pub stopped: bool,
}

/// Dampings tried for one Jacobian under [`Damping::Marquardt`] before the fit ends.
const MARQUARDT_TRIES: usize = 8;

/// Buffers of [`minimize`], sized for `P` parameters once.
#[derive(Debug, Clone)]
pub struct LmWorkspace<S> {
    np: usize,
    /// Current parameters (the result after [`minimize`]).
    pub theta: Vec<f64>,
    /// `J^T J` at `theta` (row-major, `P x P`).
    pub jtj: Vec<f64>,
    jtr: Vec<f64>,
    trial: Vec<f64>,
    jtj_trial: Vec<f64>,
    jtr_trial: Vec<f64>,
    chol: Vec<f64>,
    step: Vec<f64>,
    diag: Vec<f64>,
    lines: S,
}

impl<S> LmWorkspace<S> {
    /// Workspace for `problem` with `np` parameters.
    pub fn new<P: NormalEquations<Scratch = S>>(problem: &P, np: usize) -> Self {
        LmWorkspace {
            np,
            theta: vec![0.0; np],
            jtj: vec![0.0; np * np],
            jtr: vec![0.0; np],
            trial: vec![0.0; np],
            jtj_trial: vec![0.0; np * np],
            jtr_trial: vec![0.0; np],
            chol: vec![0.0; np * np],
            step: vec![0.0; np],
            diag: vec![0.0; np],
            lines: problem.scratch(),
        }
    }
}

/// In-place Cholesky factorisation `L L^T` of the `n x n` row-major matrix `a` (lower
/// triangle overwritten by `L`); `false` when it is not numerically positive definite.
pub(crate) fn cholesky(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut v = a[i * n + j];
            for k in 0..j {
                v -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = v / d;
        }
    }
    true
}

/// Solve `L L^T x = b` in place (`x` holds `b` on entry).
pub(crate) fn cholesky_solve(l: &[f64], n: usize, x: &mut [f64]) {
    for i in 0..n {
        let mut v = x[i];
        for k in 0..i {
            v -= l[i * n + k] * x[k];
        }
        x[i] = v / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut v = x[i];
        for k in i + 1..n {
            v -= l[k * n + i] * x[k];
        }
        x[i] = v / l[i * n + i];
    }
}

/// Minimise `problem`'s cost from `theta0`; the optimum is left in `ws.theta` and `ws.jtj`
/// (`problem` itself is left at the last parameters tried).
/// `Err` with a reason when the cost is not finite at the start.
pub fn minimize<P: NormalEquations>(
    problem: &mut P,
    theta0: &[f64],
    opts: &LmOptions,
    ws: &mut LmWorkspace<P::Scratch>,
) -> Result<LmOutcome, String> {
    minimize_until(problem, theta0, opts, ws, &|_, _, _, _| false)
}

/// [`minimize`] that also stops (with [`LmOutcome::stopped`]) as soon as
/// `stop(theta, cost, previous cost, evaluations)` holds after an accepted step.
pub fn minimize_until<P: NormalEquations>(
    problem: &mut P,
    theta0: &[f64],
    opts: &LmOptions,
    ws: &mut LmWorkspace<P::Scratch>,
    stop: &dyn Fn(&[f64], f64, f64, usize) -> bool,
) -> Result<LmOutcome, String> {
    let np = ws.np;
    ws.theta.copy_from_slice(theta0);
    problem.set_theta(&ws.theta);
    let Some(mut cost) = problem.normal_equations(&mut ws.lines, &mut ws.jtj, &mut ws.jtr) else {
        return Err("model or residuals not finite at the start".into());
    };
    let mut evals = 1;
    for j in 0..np {
        ws.diag[j] = ws.jtj[j * np + j].max(f64::MIN_POSITIVE).sqrt();
    }
    let mut lambda = 1e-3;
    let mut nu = 2.0;
    let mut converged = false;
    let mut stopped = false;
    let (marquardt, max_steps) = match opts.damping {
        Damping::Nielsen => (false, usize::MAX),
        Damping::Marquardt { max_steps } => (true, max_steps),
    };
    let (mut steps, mut rejected) = (0usize, 0usize);
    while evals < opts.max_evals.max(1) && steps < max_steps {
        // gradient test: cos(r, J_j) = |g_j| / (|J_j| |r|)
        let rn = cost.sqrt();
        if !marquardt
            && (rn == 0.0
                || (0..np).all(|j| ws.jtr[j].abs() <= opts.gtol * ws.diag[j].max(1e-300) * rn))
        {
            converged = true;
            break;
        }
        if marquardt && rejected >= MARQUARDT_TRIES {
            // no decrease at any of the dampings tried for this Jacobian
            converged = true;
            break;
        }
        ws.chol.copy_from_slice(&ws.jtj);
        for j in 0..np {
            ws.chol[j * np + j] += if marquardt {
                lambda * ws.jtj[j * np + j].max(1e-12)
            } else {
                lambda * ws.diag[j] * ws.diag[j]
            };
        }
        if !cholesky(&mut ws.chol, np) {
            if marquardt {
                lambda *= 10.0;
                rejected += 1;
                continue;
            }
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e16 {
                break;
            }
            continue;
        }
        for j in 0..np {
            ws.step[j] = -ws.jtr[j];
        }
        cholesky_solve(&ws.chol, np, &mut ws.step);
        // predicted reduction of the linear model: delta^T A delta + 2 lambda |D delta|^2
        let (mut quad, mut dstep, mut dtheta) = (0.0, 0.0, 0.0);
        for a in 0..np {
            let row = &ws.jtj[a * np..(a + 1) * np];
            let av: f64 = row.iter().zip(&ws.step).map(|(x, y)| x * y).sum();
            quad += ws.step[a] * av;
            dstep += (ws.diag[a] * ws.step[a]).powi(2);
            dtheta += (ws.diag[a] * ws.theta[a]).powi(2);
        }
        let pred = quad + 2.0 * lambda * dstep;
        let small_step = dstep.sqrt() <= opts.xtol * (dtheta.sqrt() + opts.xtol);
        for j in 0..np {
            ws.trial[j] = ws.theta[j] + ws.step[j];
        }
        problem.set_theta(&ws.trial);
        // the cost alone first: a rejected step costs no Jacobian pass
        let trial = problem.cost(&mut ws.lines).filter(|&c| {
            c < cost
                && problem.normal_after_cost(&mut ws.lines, &mut ws.jtj_trial, &mut ws.jtr_trial)
        });
        evals += 1;
        match trial {
            Some(c) => {
                let rho = (cost - c) / pred.max(f64::MIN_POSITIVE);
                let small_f = cost - c <= opts.ftol * cost && pred <= opts.ftol * cost;
                std::mem::swap(&mut ws.theta, &mut ws.trial);
                std::mem::swap(&mut ws.jtj, &mut ws.jtj_trial);
                std::mem::swap(&mut ws.jtr, &mut ws.jtr_trial);
                let prev = cost;
                cost = c;
                steps += 1;
                if stop(&ws.theta, cost, prev, evals) {
                    stopped = true;
                    break;
                }
                if marquardt {
                    rejected = 0;
                    lambda = (lambda * 0.3).max(1e-9);
                    if (prev - cost) / prev.max(1e-300) <= opts.ftol {
                        converged = true;
                        break;
                    }
                    continue;
                }
                for j in 0..np {
                    ws.diag[j] = ws.diag[j].max(ws.jtj[j * np + j].sqrt());
                }
                lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                lambda = lambda.max(1e-12);
                nu = 2.0;
                if small_f || small_step {
                    converged = true;
                    break;
                }
            }
            _ if marquardt => {
                lambda *= 10.0;
                rejected += 1;
            }
            _ => {
                lambda *= nu;
                nu *= 2.0;
                if small_step || pred <= 1e-3 * opts.ftol * cost || lambda > 1e16 {
                    // no decrease possible any more at the resolution of the cost
                    converged = small_step || pred <= 1e-3 * opts.ftol * cost;
                    break;
                }
            }
        }
    }
    Ok(LmOutcome {
        cost,
        evaluations: evals,
        converged,
        stopped,
    })
}

//! The model FRF matrix of the linearised flexible manipulator, from the motor torques
//! [N m, motor side] to the motor speeds [rad/s, motor side], and its derivatives with
//! respect to the logarithms of the spring-damper parameters.
//!
//! With the coordinates `q` of [`RigidPose`] (arm, then motors; arm side), the linearised
//! equations at rest are `M q'' + C q' + K q = P R u`:
//! * `M = diag(M_a(q_r), J_m r^2)`;
//! * `K = diag(dg/dq, 0) + sum_s k_s e_s e_s^T`, `C = sum_s c_s e_s e_s^T`, with `e_s` the
//!   difference of the coordinates pair `s` joins (gear: arm joint minus motor; bearing:
//!   the bearing coordinate alone);
//! * `P` selects the motor coordinates, `R = diag(r)`: motor torque `u_i` is `r_i u_i` on
//!   the arm side, and the motor speed is `r_i` times the arm-side one.
//!
//! With the dynamic stiffness `Z(s) = s^2 M + s C + K` (symmetric) and `X = Z^-1 P R`:
//! `G(s) = s (P R)^T X`, and since `dZ/d ln k_s = k_s e_s e_s^T`,
//! `dG/d ln k_s = -s k_s a_s^T a_s` and `dG/d ln c_s = -s^2 c_s a_s^T a_s` with the row
//! `a_s = e_s^T X` (`Z^-1` is symmetric, so `(P R)^T Z^-1 e_s = a_s^T`). One LU and `N`
//! solves per line give the FRF and every derivative. `G` is symmetric (reciprocity: the
//! paper's eq. (13)). The LU is the arm's alone, `n_a x n_a`, with the motors eliminated
//! ([`reduced`]); the full `Z` ([`full`]) where that loses precision. Several lines at
//! once ([`FrfPlan::frf_lines_into`]) take a symmetric elimination without pivoting, four
//! lines in the lanes of each vector ([`batched`]), and the pivoted LU on a line where
//! that would lose precision.
//!
//! This is the continuous-time model. The measured FRF of a sampled drive (zero-order-hold
//! torque) differs from it by a half-sample delay and a magnitude change of a few hundredths
//! of a dB at a tenth of the sample rate (`../shared/design/multiaxis.md`, fact 3); the
//! identification's cost compares magnitudes only, so the delay does not enter.

use super::pose::RigidPose;
use super::springs::Flexibilities;
use super::ManipulatorError;
use batched::{BatchedSystem, KeptLines, Rows};
use full::FullSystem;
use nalgebra::DMatrix;
use num_complex::Complex64;
use reduced::ReducedSystem;

pub mod batched;
mod full;
pub mod reduced;

/// Lines per call of [`FrfPlan::frf_lines_into`] at most.
pub const LINES_PER_BATCH: usize = batched::LANES;

/// The model FRF matrices at a set of frequencies.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelFrf {
    /// Frequencies [Hz].
    pub f_hz: Vec<f64>,
    /// `G(j 2 pi f)` per frequency, `N x N` [rad/s per N m, motor side]: row = speed of
    /// motor `n`, column = torque of motor `m`.
    pub g: Vec<DMatrix<Complex64>>,
}

/// The evaluation of one pose's model FRF, planned once: the base matrices and every
/// buffer of the per-line solve (nothing is allocated per line).
#[derive(Debug, Clone)]
pub struct FrfPlan {
    /// Axes `N`.
    axes: usize,
    /// Per pair: the coordinates it joins (`e_s = e_a - e_m`).
    pairs: Vec<(usize, Option<usize>)>,
    /// Motor coordinate and gear ratio per axis.
    motors: Vec<(usize, f64)>,
    /// The full system (every line where the reduced one does not apply).
    full: FullSystem,
    /// The arm's system with the motors eliminated, where the pose allows it.
    reduced: Option<ReducedSystem>,
    /// The same, [`LINES_PER_BATCH`] lines at once without pivoting.
    batched: Option<BatchedSystem>,
    /// `X = Z^-1 P R` (`n x N`, row-major).
    x: Vec<Complex64>,
    /// The rows `a_s` of every pair (`S x N`) and the derivative factors (`2 S`) of
    /// [`FrfPlan::frf_and_derivatives_into`].
    rows: Vec<Complex64>,
    factors: Vec<Complex64>,
    /// Per batch of lines: its last solve by [`FrfPlan::frf_lines_keep_into`], for
    /// [`FrfPlan::frf_and_pair_rows_lines_kept_into`] (allocated at a batch's first use).
    kept: Vec<KeptLines>,
}

impl FrfPlan {
    /// The plan of `pose`.
    pub fn new(pose: &RigidPose) -> Self {
        let n = pose.coords();
        let axes = pose.axes();
        FrfPlan {
            axes,
            pairs: pose.springs.iter().map(|s| pose.spring_coords(s)).collect(),
            motors: (0..axes)
                .map(|i| (pose.motor_coord(i), pose.motors[i].gear_ratio))
                .collect(),
            full: FullSystem::new(pose),
            reduced: ReducedSystem::new(pose),
            batched: BatchedSystem::new(pose),
            x: vec![Complex64::new(0.0, 0.0); n * axes],
            rows: vec![Complex64::new(0.0, 0.0); pose.springs.len() * axes],
            factors: vec![Complex64::new(0.0, 0.0); 2 * pose.springs.len()],
            kept: Vec::new(),
        }
    }

    /// The plan of `pose` that always solves the full `Z` (the tests' reference).
    #[cfg(test)]
    pub(crate) fn full_form(pose: &RigidPose) -> Self {
        FrfPlan {
            reduced: None,
            batched: None,
            ..FrfPlan::new(pose)
        }
    }

    /// Number of axes `N`.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Number of spring-damper pairs.
    pub fn pairs(&self) -> usize {
        self.pairs.len()
    }

    /// `G(j 2 pi f_hz)` into `g` (`N x N` row-major).
    pub fn frf_into(
        &mut self,
        f_hz: f64,
        theta: &Flexibilities,
        g: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let s = self.solve(f_hz, theta)?;
        self.gather(s, g);
        Ok(())
    }

    /// `G(j 2 pi f_hz)` into `g` and its derivatives into `dg` (`2 S` blocks of `N x N`
    /// row-major: `d/d ln k_1 .. d/d ln k_S`, then `d/d ln c_1 .. d/d ln c_S`).
    pub fn frf_and_derivatives_into(
        &mut self,
        f_hz: f64,
        theta: &Flexibilities,
        g: &mut [Complex64],
        dg: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let npairs = self.pairs.len();
        let nn = self.axes * self.axes;
        let (mut rows, mut factors) = (
            std::mem::take(&mut self.rows),
            std::mem::take(&mut self.factors),
        );
        let out = self.frf_and_pair_rows_into(f_hz, theta, g, &mut rows, &mut factors);
        for p in (0..npairs).filter(|_| out.is_ok()) {
            let a = &rows[p * self.axes..(p + 1) * self.axes];
            let (fk, fc) = (factors[p], factors[npairs + p]);
            let (dk, rest) = dg[p * nn..].split_at_mut(nn);
            let dc = &mut rest[(npairs - 1) * nn..npairs * nn];
            for i in 0..self.axes {
                for j in 0..self.axes {
                    let aa = a[i] * a[j];
                    dk[i * self.axes + j] = fk * aa;
                    dc[i * self.axes + j] = fc * aa;
                }
            }
        }
        self.rows = rows;
        self.factors = factors;
        out
    }

    /// `G(j 2 pi f_hz)` into `g` and its derivatives in factored form:
    /// `dG / d theta_p = factors[p] a_s^T a_s` with the row `a_s` of pair `s = p mod S`
    /// in `rows[s N..(s + 1) N]` and `factors` `-s k_1 .. -s k_S, -s^2 c_1 .. -s^2 c_S`
    /// [N m/rad] (what a caller needing a few elements of the `2 S` derivatives takes, at
    /// `O(S N)` per line instead of `O(S N^2)`).
    pub fn frf_and_pair_rows_into(
        &mut self,
        f_hz: f64,
        theta: &Flexibilities,
        g: &mut [Complex64],
        rows: &mut [Complex64],
        factors: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let s = self.solve(f_hz, theta)?;
        self.gather(s, g);
        self.pair_rows_into(s, theta, rows, factors);
        Ok(())
    }

    /// `G` at the lines `f_hz` (at most [`LINES_PER_BATCH`]) into `g` (one `N x N`
    /// row-major block per line): [`FrfPlan::frf_into`] of each line, the lines solved
    /// together ([`batched`]).
    pub fn frf_lines_into(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
        g: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let nn = self.axes * self.axes;
        let solved = self.solve_lines(f_hz, theta, Rows::Gears);
        for (lane, (&f, g)) in f_hz.iter().zip(g.chunks_exact_mut(nn)).enumerate() {
            let batched = match &self.batched {
                Some(b) if solved[lane] => {
                    b.g_into(lane, g);
                    true
                }
                _ => false,
            };
            if !batched {
                self.frf_into(f, theta, g)?;
            }
        }
        Ok(())
    }

    /// [`FrfPlan::frf_lines_into`], the solve kept as batch number `batch` of the caller's
    /// (its factorisation `L D L^T` and the gears' rows of `X_a`), for a later
    /// [`FrfPlan::frf_and_pair_rows_lines_kept_into`] at the same lines and `theta`.
    pub fn frf_lines_keep_into(
        &mut self,
        batch: usize,
        f_hz: &[f64],
        theta: &Flexibilities,
        g: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let Some(b) = &mut self.batched else {
            return self.frf_lines_into(f_hz, theta, g);
        };
        while self.kept.len() <= batch {
            self.kept.push(b.kept_lines());
        }
        let nn = self.axes * self.axes;
        let kept = &mut self.kept[batch];
        b.swap_lines(kept);
        let solved = b.solve(f_hz, theta, Rows::Gears);
        for (lane, g) in g.chunks_exact_mut(nn).take(f_hz.len()).enumerate() {
            if solved[lane] {
                b.g_into(lane, g);
            }
        }
        b.swap_lines(kept);
        kept.solved = solved;
        kept.rows = Rows::Gears;
        for (lane, (&f, g)) in f_hz.iter().zip(g.chunks_exact_mut(nn)).enumerate() {
            if !solved[lane] {
                self.frf_into(f, theta, g)?;
            }
        }
        Ok(())
    }

    /// [`FrfPlan::frf_and_pair_rows_lines_into`] from the solve kept as batch `batch` by
    /// [`FrfPlan::frf_lines_keep_into`], which must have been at the same lines `f_hz` and
    /// `theta`: only the rows of `X_a` above the gears are solved (the same bits as a
    /// fresh solve); the lines the elimination did not solve take the pivoted solve.
    pub fn frf_and_pair_rows_lines_kept_into(
        &mut self,
        batch: usize,
        f_hz: &[f64],
        theta: &Flexibilities,
        g: &mut [Complex64],
        rows: &mut [Complex64],
        factors: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let (Some(b), Some(kept)) = (&mut self.batched, self.kept.get_mut(batch)) else {
            return self.frf_and_pair_rows_lines_into(f_hz, theta, g, rows, factors);
        };
        b.swap_lines(kept);
        if kept.rows == Rows::Gears {
            b.finish_rows();
        }
        let solved = kept.solved;
        kept.rows = Rows::All;
        let out = self.pair_rows_of_solved(&solved, f_hz, theta, g, rows, factors);
        if let (Some(b), Some(kept)) = (&mut self.batched, self.kept.get_mut(batch)) {
            b.swap_lines(kept);
        }
        out
    }

    /// [`FrfPlan::frf_and_pair_rows_into`] at the lines `f_hz` (at most
    /// [`LINES_PER_BATCH`]), solved together: per line one block of `g` (`N x N`), of
    /// `rows` (`S x N`) and of `factors` (`2 S`).
    pub fn frf_and_pair_rows_lines_into(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
        g: &mut [Complex64],
        rows: &mut [Complex64],
        factors: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let solved = self.solve_lines(f_hz, theta, Rows::All);
        self.pair_rows_of_solved(&solved, f_hz, theta, g, rows, factors)
    }

    /// The rest of [`FrfPlan::frf_and_pair_rows_lines_into`] once the batched system holds
    /// the solve of every row at `f_hz`: the lanes `solved` from it, the others by the
    /// pivoted solve.
    fn pair_rows_of_solved(
        &mut self,
        solved: &[bool; LINES_PER_BATCH],
        f_hz: &[f64],
        theta: &Flexibilities,
        g: &mut [Complex64],
        rows: &mut [Complex64],
        factors: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let nn = self.axes * self.axes;
        let (nr, nf) = (self.pairs.len() * self.axes, 2 * self.pairs.len());
        for (lane, (((&f, g), rows), factors)) in f_hz
            .iter()
            .zip(g.chunks_exact_mut(nn))
            .zip(rows.chunks_exact_mut(nr))
            .zip(factors.chunks_exact_mut(nf))
            .enumerate()
        {
            let batched = match &self.batched {
                Some(b) if solved[lane] => {
                    b.x_into(lane, &mut self.x);
                    Some(b.s(lane))
                }
                _ => None,
            };
            match batched {
                Some(s) => {
                    self.gather(s, g);
                    self.pair_rows_into(s, theta, rows, factors);
                }
                None => self.frf_and_pair_rows_into(f, theta, g, rows, factors)?,
            }
        }
        Ok(())
    }

    /// The batched solve of the lines `f_hz`, if the plan has one: which lanes it solved.
    fn solve_lines(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
        rows: Rows,
    ) -> [bool; LINES_PER_BATCH] {
        debug_assert!(f_hz.len() <= LINES_PER_BATCH);
        debug_assert_eq!(theta.pairs(), self.pairs.len());
        match &mut self.batched {
            Some(b) => b.solve(f_hz, theta, rows),
            None => [false; LINES_PER_BATCH],
        }
    }

    /// The pair rows `a_s` and derivative factors of [`FrfPlan::frf_and_pair_rows_into`]
    /// from the solved `X`.
    fn pair_rows_into(
        &self,
        s: Complex64,
        theta: &Flexibilities,
        rows: &mut [Complex64],
        factors: &mut [Complex64],
    ) {
        let npairs = self.pairs.len();
        let axes = self.axes;
        for (p, &(a, m)) in self.pairs.iter().enumerate() {
            let row = &mut rows[p * axes..(p + 1) * axes];
            let xa = &self.x[a * axes..(a + 1) * axes];
            match m {
                Some(m) => {
                    let xm = &self.x[m * axes..(m + 1) * axes];
                    for ((r, xa), xm) in row.iter_mut().zip(xa).zip(xm) {
                        *r = xa - xm;
                    }
                }
                None => row.copy_from_slice(xa),
            }
            factors[p] = -s * theta.stiffness_nm_per_rad[p];
            factors[npairs + p] = -s * s * theta.damping_nms_per_rad[p];
        }
    }

    /// The FRF matrices at every frequency of `f_hz`.
    pub fn frf(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
    ) -> Result<ModelFrf, ManipulatorError> {
        let mut buf = vec![Complex64::new(0.0, 0.0); self.axes * self.axes];
        let g = f_hz
            .iter()
            .map(|&f| {
                self.frf_into(f, theta, &mut buf)?;
                Ok(DMatrix::from_row_slice(self.axes, self.axes, &buf))
            })
            .collect::<Result<Vec<_>, ManipulatorError>>()?;
        Ok(ModelFrf {
            f_hz: f_hz.to_vec(),
            g,
        })
    }

    /// Solves `X = Z(s)^-1 P R` at `s = j 2 pi f_hz` (the reduced system, else the full
    /// one); returns `s`.
    fn solve(&mut self, f_hz: f64, theta: &Flexibilities) -> Result<Complex64, ManipulatorError> {
        debug_assert_eq!(theta.pairs(), self.pairs.len());
        let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f_hz);
        if let Some(r) = &mut self.reduced {
            if r.solve(s, theta, &mut self.x) {
                return Ok(s);
            }
        }
        if !self
            .full
            .solve(s, theta, &self.pairs, &self.motors, &mut self.x)
        {
            return Err(ManipulatorError::Singular { f_hz });
        }
        Ok(s)
    }

    /// `G = s (P R)^T X` from the solved `X`.
    fn gather(&self, s: Complex64, g: &mut [Complex64]) {
        for (i, &(c, r)) in self.motors.iter().enumerate() {
            for j in 0..self.axes {
                g[i * self.axes + j] = s * r * self.x[c * self.axes + j];
            }
        }
    }
}

#[cfg(test)]
mod tests;

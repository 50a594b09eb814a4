//! Four lines at once: [`super::FrfPlan`]'s solve of the motor-eliminated arm system
//! ([`super::reduced`]: `S X_a = B`, `n_a x n_a`) as a symmetric elimination
//! `S = L D L^T` without pivoting, each value holding the same entry of four lines (one
//! line per lane), so that every operation is one vector operation over the four lines.
//!
//! Why it applies: `S = K_0 - w^2 M_a + diag(springs)` is complex **symmetric** (`M_a`,
//! `K_0` symmetric, every spring on the diagonal once the motors are eliminated), so
//! `L D L^T` needs half the elimination of an LU; and without pivoting every line runs
//! the same operations, which is what lets four lines share a vector register (a pivoted
//! LU swaps different rows on different lines). The pivoted LU ([`super::reduced`], then
//! the full `Z`) stays the reference and the fallback: a line whose elimination meets a
//! multiplier `|l_ik| > MAX_MULTIPLIER` (a pivot small against its column: the element
//! growth that pivoting exists to avoid), a pivot zero or not finite, or a motor not
//! eliminated to full precision ([`super::reduced::MIN_D_OVER_W`]) is solved again there.
//!
//! The order of the unknowns: the arm coordinates without a gear (the bearings) first,
//! then the gears' arm coordinates in axis order. `B` is non-zero only in the gears' rows
//! (`w_i r_i / d_i` at `(a_i, i)`), so the forward substitution starts at the first gear,
//! and `G` needs `X_a` only in the gears' rows: the cost pass stops the back substitution
//! there (the last `N` rows), the derivatives' pass runs it to the top. A batch's solve can
//! be kept aside ([`KeptLines`], swapped in and out without copying): the derivatives'
//! pass at the same parameters then runs only the rest of the backward substitution
//! ([`BatchedSystem::finish_rows`]), the same operations in the same order as a fresh
//! solve of every row, so the same bits.
//!
//! Arithmetic per line for the paper's robot (12 arm coordinates, 6 axes): about 290
//! complex multiply-adds for `L D L^T` and 200 for the cost pass's substitutions, against
//! about 1440 for the pivoted `[S | B]` elimination ([`super::super::augmented`]).

use super::super::pose::RigidPose;
use super::super::springs::Flexibilities;
use super::reduced::{gears_and_bearings, Gear, MIN_D_OVER_W};
use num_complex::Complex64;

/// Lines per batch (the lanes of an AVX2 register of `f64`).
pub const LANES: usize = 4;

/// One value of every lane.
type Lanes = [f64; LANES];

const ZERO: Lanes = [0.0; LANES];

/// The largest multiplier `|l_ik| = |s_ik| / |d_k|` the elimination accepts without
/// pivoting. Each step adds at most `MAX_MULTIPLIER^2` times a pivot row's round-off to
/// an entry, so with `n = 12` the solution keeps at least
/// `1e-16 * 12 * 1e4 ~ 1e-11` of relative precision where it is taken; a line beyond it
/// goes to the pivoted LU (checked against it to 1e-10 in the tests, on every line of the
/// reference robot's poses at the benchmark's starts).
pub const MAX_MULTIPLIER: f64 = 1e2;

/// Which rows of `X` a batch computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Rows {
    /// The gears' rows (what `G` needs): the cost pass.
    Gears,
    /// Every row (what the derivatives' pair rows need).
    All,
}

/// The batched system of one pose: the arm's base matrices in the elimination's order and
/// the buffers of four lines.
#[derive(Debug, Clone)]
pub(super) struct BatchedSystem {
    /// Arm coordinates `n_a`.
    na: usize,
    /// Positions `0..free` hold the arm coordinates without a gear, `free..n_a` the gears'
    /// in axis order.
    free: usize,
    /// The arm coordinate at each position.
    coord: Vec<usize>,
    /// `M_a` and `dg/dq` in position order, packed lower triangles [kg m^2], [N m/rad].
    mass: Vec<f64>,
    gravity: Vec<f64>,
    /// Bearing pairs: index, position.
    bearings: Vec<(usize, usize)>,
    /// Per axis (position `free + i`).
    gears: Vec<Gear>,
    /// The lines' state: what a kept solve holds.
    lines: LineState,
    /// One column of `S` and its multipliers during a step of the elimination.
    cr: Vec<Lanes>,
    ci: Vec<Lanes>,
    lr: Vec<Lanes>,
    li: Vec<Lanes>,
}

/// The state of a batch's lines in a [`BatchedSystem`]: its factorisation, solution and
/// the springs' terms, all a later pass at the same parameters takes up.
#[derive(Debug, Clone)]
struct LineState {
    /// `S` (packed lower triangle), then `L` below the diagonal and `D` on it: real and
    /// imaginary parts.
    tr: Vec<Lanes>,
    ti: Vec<Lanes>,
    /// `1 / D` per position.
    inv_r: Vec<Lanes>,
    inv_i: Vec<Lanes>,
    /// `B`, then `X_a` (`n_a x N`, position-major).
    xr: Vec<Lanes>,
    xi: Vec<Lanes>,
    /// Per axis: `w_i = k_i + s c_i` and `1 / d_i`.
    wr: Vec<Lanes>,
    wi: Vec<Lanes>,
    dr: Vec<Lanes>,
    di: Vec<Lanes>,
    /// `w = 2 pi f` per lane [rad/s].
    omega: Lanes,
}

/// One batch's solve kept aside ([`BatchedSystem::swap_lines`]): the fields of
/// [`BatchedSystem`] that hold the lines' state, and which lanes the elimination solved
/// and for which rows.
#[derive(Debug, Clone)]
pub(super) struct KeptLines {
    lines: LineState,
    /// Per lane: solved by the elimination (else by the pivoted solve when asked).
    pub(super) solved: [bool; LANES],
    /// The rows of `X_a` solved.
    pub(super) rows: Rows,
}

/// Index of `(i, j)`, `j <= i`, in a packed lower triangle.
fn tri(i: usize, j: usize) -> usize {
    i * (i + 1) / 2 + j
}

impl BatchedSystem {
    /// The system of `pose`; `None` where the motors are not eliminated
    /// ([`super::reduced::ReducedSystem::new`]'s conditions: every axis has a gear, the
    /// motors are the last coordinates).
    pub(super) fn new(pose: &RigidPose) -> Option<Self> {
        let na = pose.arm_coords();
        let axes = pose.axes();
        let (gears, bearing_pairs) = gears_and_bearings(pose)?;
        let geared: Vec<usize> = gears.iter().map(|g| g.arm).collect();
        let mut coord: Vec<usize> = (0..na).filter(|c| !geared.contains(c)).collect();
        let free = coord.len();
        coord.extend(&geared);
        let position = |c: usize| coord.iter().position(|&x| x == c);
        let bearings = bearing_pairs
            .iter()
            .map(|&(p, c)| Some((p, position(c)?)))
            .collect::<Option<Vec<_>>>()?;
        let packed = |m: &nalgebra::DMatrix<f64>| -> Vec<f64> {
            (0..na)
                .flat_map(|i| (0..=i).map(move |j| (i, j)))
                .map(|(i, j)| m[(coord[i], coord[j])])
                .collect()
        };
        let lanes = |len: usize| vec![ZERO; len];
        Some(BatchedSystem {
            na,
            free,
            mass: packed(&pose.arm_mass),
            gravity: packed(&pose.gravity_stiffness),
            coord,
            bearings,
            gears,
            lines: LineState {
                tr: lanes(tri(na, 0)),
                ti: lanes(tri(na, 0)),
                inv_r: lanes(na),
                inv_i: lanes(na),
                xr: lanes(na * axes),
                xi: lanes(na * axes),
                wr: lanes(axes),
                wi: lanes(axes),
                dr: lanes(axes),
                di: lanes(axes),
                omega: ZERO,
            },
            cr: lanes(na),
            ci: lanes(na),
            lr: lanes(na),
            li: lanes(na),
        })
    }

    /// Solves the lines `f_hz` (at most [`LANES`]; the unused lanes repeat the last line)
    /// for the `rows` of `X_a`; returns per lane whether the elimination solved it (else the
    /// pivoted solve must).
    pub(super) fn solve(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
        rows: Rows,
    ) -> [bool; LANES] {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above)
            return unsafe { self.solve_avx2(f_hz, theta, rows) };
        }
        self.solve_here(f_hz, theta, rows)
    }

    /// [`BatchedSystem::solve`] compiled for AVX2 (four lanes a register instead of two;
    /// no fused multiply-adds, so the result is the same to the bit).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn solve_avx2(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
        rows: Rows,
    ) -> [bool; LANES] {
        self.solve_here(f_hz, theta, rows)
    }

    /// [`BatchedSystem::solve`] as compiled for any CPU.
    #[inline(always)]
    pub(super) fn solve_here(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
        rows: Rows,
    ) -> [bool; LANES] {
        let mut ok = [false; LANES];
        let Some(&last) = f_hz.last() else {
            return ok;
        };
        for (l, w) in self.lines.omega.iter_mut().enumerate() {
            *w = 2.0 * std::f64::consts::PI * f_hz.get(l).copied().unwrap_or(last);
        }
        ok = [true; LANES];
        self.assemble(theta, &mut ok);
        self.factor(&mut ok);
        self.substitute(rows);
        for (l, ok) in ok.iter_mut().enumerate() {
            *ok &= l < f_hz.len();
        }
        ok
    }

    /// `S` and `B` of the lanes' lines; clears `ok` of a lane whose motor is not
    /// eliminated to full precision.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // a lane of several parallel arrays
    fn assemble(&mut self, theta: &Flexibilities, ok: &mut [bool; LANES]) {
        let w = self.lines.omega;
        let mut w2 = ZERO;
        for l in 0..LANES {
            w2[l] = -(w[l] * w[l]);
        }
        for (((tr, ti), &m), &k) in self
            .lines
            .tr
            .iter_mut()
            .zip(self.lines.ti.iter_mut())
            .zip(&self.mass)
            .zip(&self.gravity)
        {
            for l in 0..LANES {
                tr[l] = k + w2[l] * m;
            }
            *ti = ZERO;
        }
        for &(p, b) in &self.bearings {
            let (k, c) = (theta.stiffness_nm_per_rad[p], theta.damping_nms_per_rad[p]);
            let d = tri(b, b);
            for l in 0..LANES {
                self.lines.tr[d][l] += k;
                self.lines.ti[d][l] += w[l] * c;
            }
        }
        self.lines.xr.fill(ZERO);
        self.lines.xi.fill(ZERO);
        let axes = self.gears.len();
        for (i, g) in self.gears.iter().enumerate() {
            let (k, c) = (
                theta.stiffness_nm_per_rad[g.pair],
                theta.damping_nms_per_rad[g.pair],
            );
            let pos = self.free + i;
            let dpos = tri(pos, pos);
            for l in 0..LANES {
                // w = k + j w c, s^2 m = -w^2 m, d = s^2 m + w
                let (wr, wi) = (k, w[l] * c);
                let sm = w2[l] * g.inertia;
                let (dr, di) = (sm + wr, wi);
                let d2 = dr * dr + di * di;
                // also false for a NaN
                ok[l] &= d2 >= MIN_D_OVER_W * MIN_D_OVER_W * (wr * wr + wi * wi) && d2 > 0.0;
                let (ir, ii) = (dr / d2, -di / d2);
                // w s^2 m / d on the diagonal, w r / d in B
                let (qr, qi) = (wr * ir - wi * ii, wr * ii + wi * ir);
                self.lines.tr[dpos][l] += qr * sm;
                self.lines.ti[dpos][l] += qi * sm;
                self.lines.xr[pos * axes + i][l] = qr * g.ratio;
                self.lines.xi[pos * axes + i][l] = qi * g.ratio;
                self.lines.wr[i][l] = wr;
                self.lines.wi[i][l] = wi;
                self.lines.dr[i][l] = ir;
                self.lines.di[i][l] = ii;
            }
        }
    }

    /// `S = L D L^T` in place, `1 / D` apart; clears `ok` of a lane with a pivot zero or
    /// not finite, or a multiplier above [`MAX_MULTIPLIER`].
    #[inline(always)]
    fn factor(&mut self, ok: &mut [bool; LANES]) {
        let na = self.na;
        let bound = MAX_MULTIPLIER * MAX_MULTIPLIER;
        for k in 0..na {
            let d = tri(k, k);
            let (dr, di) = (self.lines.tr[d], self.lines.ti[d]);
            let (mut ir, mut ii, mut d2) = (ZERO, ZERO, ZERO);
            for l in 0..LANES {
                d2[l] = dr[l] * dr[l] + di[l] * di[l];
                ok[l] &= d2[l] > 0.0 && d2[l].is_finite();
                ir[l] = dr[l] / d2[l];
                ii[l] = -di[l] / d2[l];
            }
            self.lines.inv_r[k] = ir;
            self.lines.inv_i[k] = ii;
            // column k below the diagonal, and its multipliers l_ik = s_ik / d_k
            for i in k + 1..na {
                let (cr, ci) = (self.lines.tr[tri(i, k)], self.lines.ti[tri(i, k)]);
                let (mut lr, mut li) = (ZERO, ZERO);
                for l in 0..LANES {
                    ok[l] &= cr[l] * cr[l] + ci[l] * ci[l] <= bound * d2[l];
                    lr[l] = cr[l] * ir[l] - ci[l] * ii[l];
                    li[l] = cr[l] * ii[l] + ci[l] * ir[l];
                }
                self.cr[i] = cr;
                self.ci[i] = ci;
                self.lr[i] = lr;
                self.li[i] = li;
            }
            // the trailing triangle: s_ij -= l_i s_jk (row i from column k + 1 on is
            // contiguous in the packed triangle)
            for i in k + 1..na {
                let (lr, li) = (self.lr[i], self.li[i]);
                let row = tri(i, k + 1)..tri(i, i) + 1;
                for ((tr, ti), (cr, ci)) in self.lines.tr[row.clone()]
                    .iter_mut()
                    .zip(self.lines.ti[row].iter_mut())
                    .zip(self.cr[k + 1..=i].iter().zip(&self.ci[k + 1..=i]))
                {
                    sub_product(tr, ti, &lr, &li, cr, ci);
                }
            }
            for i in k + 1..na {
                self.lines.tr[tri(i, k)] = self.lr[i];
                self.lines.ti[tri(i, k)] = self.li[i];
            }
        }
    }

    /// `X_a = L^-T D^-1 L^-1 B` for the `rows` asked: `B` is zero above the first gear, so
    /// the forward substitution starts there.
    #[inline(always)]
    fn substitute(&mut self, rows: Rows) {
        let (na, free) = (self.na, self.free);
        let axes = self.gears.len();
        let (xr, xi) = (&mut self.lines.xr, &mut self.lines.xi);
        // forward: L y = B (rows of B above `free` are zero and stay so)
        for i in free..na {
            for k in free..i {
                let (lr, li) = (self.lines.tr[tri(i, k)], self.lines.ti[tri(i, k)]);
                row_sub_product(xr, xi, axes, i, k, &lr, &li);
            }
        }
        // D^-1
        for i in free..na {
            let (ir, ii) = (self.lines.inv_r[i], self.lines.inv_i[i]);
            for (r, m) in xr[i * axes..(i + 1) * axes]
                .iter_mut()
                .zip(&mut xi[i * axes..(i + 1) * axes])
            {
                let (a, b) = (*r, *m);
                for l in 0..LANES {
                    r[l] = a[l] * ir[l] - b[l] * ii[l];
                    m[l] = a[l] * ii[l] + b[l] * ir[l];
                }
            }
        }
        // backward: L^T x = y, from the last row up to the gears' first (the cost pass) or
        // to the top
        self.back_substitute(free..na);
        if rows == Rows::All {
            self.back_substitute(0..free);
        }
    }

    /// The rows `rows` of the backward substitution `L^T x = y`, from the last up (the
    /// rows below them already solved).
    #[inline(always)]
    fn back_substitute(&mut self, rows: std::ops::Range<usize>) {
        let na = self.na;
        let axes = self.gears.len();
        let (xr, xi) = (&mut self.lines.xr, &mut self.lines.xi);
        for i in rows.rev() {
            for k in i + 1..na {
                let (lr, li) = (self.lines.tr[tri(k, i)], self.lines.ti[tri(k, i)]);
                row_sub_product(xr, xi, axes, i, k, &lr, &li);
            }
        }
    }

    /// After a solve of [`Rows::Gears`] (its factorisation and gears' rows kept, or swapped
    /// back in with [`BatchedSystem::swap_lines`]): the rows above the gears, so that `X_a`
    /// is that of a solve of [`Rows::All`] to the bit (the same operations in the same
    /// order: the backward substitution of the bearings' rows needs only `L` and the rows
    /// below them).
    pub(super) fn finish_rows(&mut self) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above)
            unsafe { self.finish_rows_avx2() };
            return;
        }
        self.back_substitute(0..self.free);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn finish_rows_avx2(&mut self) {
        self.back_substitute(0..self.free);
    }

    /// Exchanges the state of the lines solved last (factorisation, `X_a`, the motors'
    /// `w_i` and `1 / d_i`, the lines' `w`) with `kept`'s: four lines' solve kept aside
    /// without copying, and taken up again later.
    pub(super) fn swap_lines(&mut self, kept: &mut KeptLines) {
        std::mem::swap(&mut self.lines, &mut kept.lines);
    }

    /// Buffers to keep one batch's solve in ([`BatchedSystem::swap_lines`]), sized as the
    /// system's.
    pub(super) fn kept_lines(&self) -> KeptLines {
        KeptLines {
            lines: self.lines.clone(),
            solved: [false; LANES],
            rows: Rows::Gears,
        }
    }

    /// `G(j 2 pi f)` of `lane` into `g` (`N x N` row-major) from the gears' rows of `X_a`:
    /// `G_ij = s r_i X_m,ij` with `X_m,ij = (r_i delta_ij + w_i X_a,gear_i j) / d_i`.
    pub(super) fn g_into(&self, lane: usize, g: &mut [Complex64]) {
        let axes = self.gears.len();
        let s = Complex64::new(0.0, self.lines.omega[lane]);
        for (i, gear) in self.gears.iter().enumerate() {
            for j in 0..axes {
                g[i * axes + j] = s * gear.ratio * self.motor_x(i, j, lane);
            }
        }
    }

    /// `X = Z^-1 P R` of `lane` into `x` (`(n_a + N) x N` row-major: arm rows, then motor
    /// rows), after a solve of [`Rows::All`].
    pub(super) fn x_into(&self, lane: usize, x: &mut [Complex64]) {
        let axes = self.gears.len();
        for (p, &c) in self.coord.iter().enumerate() {
            for j in 0..axes {
                x[c * axes + j] = self.x(p * axes + j, lane);
            }
        }
        for i in 0..axes {
            for j in 0..axes {
                x[(self.na + i) * axes + j] = self.motor_x(i, j, lane);
            }
        }
    }

    /// `s = j 2 pi f` of `lane`.
    pub(super) fn s(&self, lane: usize) -> Complex64 {
        Complex64::new(0.0, self.lines.omega[lane])
    }

    fn x(&self, k: usize, lane: usize) -> Complex64 {
        Complex64::new(self.lines.xr[k][lane], self.lines.xi[k][lane])
    }

    /// `X_m,ij = (r_i delta_ij + w_i X_a,gear_i j) / d_i` of `lane`.
    fn motor_x(&self, i: usize, j: usize, lane: usize) -> Complex64 {
        let axes = self.gears.len();
        let w = Complex64::new(self.lines.wr[i][lane], self.lines.wi[i][lane]);
        let inv = Complex64::new(self.lines.dr[i][lane], self.lines.di[i][lane]);
        let mut xm = w * self.x((self.free + i) * axes + j, lane);
        if i == j {
            xm += self.gears[i].ratio;
        }
        xm * inv
    }
}

/// `t -= a c` lane by lane (complex, real and imaginary parts apart).
#[inline(always)]
fn sub_product(tr: &mut Lanes, ti: &mut Lanes, ar: &Lanes, ai: &Lanes, cr: &Lanes, ci: &Lanes) {
    for l in 0..LANES {
        tr[l] -= ar[l] * cr[l] - ai[l] * ci[l];
        ti[l] -= ar[l] * ci[l] + ai[l] * cr[l];
    }
}

/// Row `i` of `x` (`axes` values a row) minus `a` times row `k` (`i != k`).
#[inline(always)]
fn row_sub_product(
    xr: &mut [Lanes],
    xi: &mut [Lanes],
    axes: usize,
    i: usize,
    k: usize,
    ar: &Lanes,
    ai: &Lanes,
) {
    let (ri, rk) = rows_apart(xr, axes, i, k);
    let (ii, ik) = rows_apart(xi, axes, i, k);
    for ((tr, ti), (cr, ci)) in ri
        .iter_mut()
        .zip(ii.iter_mut())
        .zip(rk.iter().zip(ik.iter()))
    {
        sub_product(tr, ti, ar, ai, cr, ci);
    }
}

/// Row `i` (mutable) and row `k` (`i != k`) of a row-major `x` of `axes` values a row.
#[inline(always)]
fn rows_apart(x: &mut [Lanes], axes: usize, i: usize, k: usize) -> (&mut [Lanes], &[Lanes]) {
    if i < k {
        let (top, bottom) = x.split_at_mut(k * axes);
        (&mut top[i * axes..(i + 1) * axes], &bottom[..axes])
    } else {
        let (top, bottom) = x.split_at_mut(i * axes);
        (&mut bottom[..axes], &top[k * axes..(k + 1) * axes])
    }
}

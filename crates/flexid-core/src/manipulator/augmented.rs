//! A small dense complex system `A X = B` solved by Gauss elimination with partial
//! pivoting on the augmented matrix `[A | B]`, stored as separate real and imaginary
//! parts (rows padded to whole groups of [`LANES`] values): the motor-eliminated model
//! FRF's solve per line ([`super::frf`]), `12 x 12` with 6 right-hand sides for the
//! paper's robot, hundreds of lines per pose and step.
//!
//! Why not [`super::clu`] (the same elimination on interleaved `Complex64`): there every
//! complex multiply-add needs shuffles, and a row of 12 numbers is too short for the
//! compiler to do better; here a row update is `LANES`-wide real arithmetic on whole padded
//! groups (no remainder loop), which vectorises as it stands. Both do the same arithmetic
//! (partial pivoting by the largest `|a|^2`), so the results agree to round-off; `clu` is
//! the reference in the tests below.

use num_complex::Complex64;

/// Values per padded group of a row.
pub const LANES: usize = 4;

/// `[A | B]` of an `n x n` system with `m` right-hand sides, planned once.
#[derive(Debug, Clone)]
pub struct Augmented {
    n: usize,
    m: usize,
    /// First column of `B` (`n` rounded up to whole groups).
    rhs: usize,
    /// Values per row (`rhs + m` rounded up to whole groups).
    stride: usize,
    re: Vec<f64>,
    im: Vec<f64>,
}

impl Augmented {
    /// An all-zero system of `n` unknowns and `m` right-hand sides.
    pub fn new(n: usize, m: usize) -> Self {
        let rhs = n.next_multiple_of(LANES);
        let stride = (rhs + m).next_multiple_of(LANES).max(LANES);
        Augmented {
            n,
            m,
            rhs,
            stride,
            re: vec![0.0; n * stride],
            im: vec![0.0; n * stride],
        }
    }

    /// Unknowns `n` and right-hand sides `m`.
    pub fn size(&self) -> (usize, usize) {
        (self.n, self.m)
    }

    /// `A = re_a(i, j)` (real; imaginary parts by [`Augmented::add_a`]) and `B = 0`.
    pub fn set_matrix(&mut self, re_a: impl Fn(usize, usize) -> f64) {
        let (n, stride) = (self.n, self.stride);
        for i in 0..n {
            let (r, m) = (
                &mut self.re[i * stride..(i + 1) * stride],
                &mut self.im[i * stride..(i + 1) * stride],
            );
            for (j, x) in r.iter_mut().enumerate() {
                *x = if j < n { re_a(i, j) } else { 0.0 };
            }
            m.fill(0.0);
        }
    }

    /// `A[i][j] += z`.
    pub fn add_a(&mut self, i: usize, j: usize, z: Complex64) {
        let k = i * self.stride + j;
        self.re[k] += z.re;
        self.im[k] += z.im;
    }

    /// `B[i][j] = z`.
    pub fn set_b(&mut self, i: usize, j: usize, z: Complex64) {
        let k = i * self.stride + self.rhs + j;
        self.re[k] = z.re;
        self.im[k] = z.im;
    }

    /// The solution `X[i][j]` after [`Augmented::solve`].
    pub fn x(&self, i: usize, j: usize) -> Complex64 {
        let k = i * self.stride + self.rhs + j;
        Complex64::new(self.re[k], self.im[k])
    }

    /// Solves in place (`B` becomes `X`); `false` when a pivot is exactly zero or not
    /// finite (singular to working precision). On an x86-64 with AVX2 the same code runs
    /// compiled for it (4 lanes a register instead of 2; no fused multiply-adds, so the
    /// result is the same to the bit).
    pub fn solve(&mut self) -> bool {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above)
            return unsafe { self.solve_avx2() };
        }
        self.solve_here()
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn solve_avx2(&mut self) -> bool {
        self.solve_here()
    }

    #[inline(always)]
    fn solve_here(&mut self) -> bool {
        let (n, stride, rhs) = (self.n, self.stride, self.rhs);
        let (re, im) = (&mut self.re[..], &mut self.im[..]);
        for k in 0..n {
            // the largest |a|^2 in column k on and below the diagonal (a NaN wins)
            let mut p = k;
            let mut best = re[k * stride + k].powi(2) + im[k * stride + k].powi(2);
            for i in k + 1..n {
                let v = re[i * stride + k].powi(2) + im[i * stride + k].powi(2);
                if v > best || v.is_nan() {
                    best = v;
                    p = i;
                    if v.is_nan() {
                        break;
                    }
                }
            }
            if !(best > 0.0 && best.is_finite()) {
                return false;
            }
            if p != k {
                swap_rows(re, stride, k, p);
                swap_rows(im, stride, k, p);
            }
            let inv = Complex64::new(re[k * stride + k], im[k * stride + k]).inv();
            // the row updates from the group holding column k + 1 on (the columns before
            // are not read again)
            let start = (k + 1) / LANES * LANES;
            let (re_top, re_rest) = re.split_at_mut((k + 1) * stride);
            let (im_top, im_rest) = im.split_at_mut((k + 1) * stride);
            let (rk, ik) = (
                &re_top[k * stride + start..(k + 1) * stride],
                &im_top[k * stride + start..(k + 1) * stride],
            );
            for (ri, ii) in re_rest
                .chunks_exact_mut(stride)
                .zip(im_rest.chunks_exact_mut(stride))
            {
                let l = Complex64::new(ri[k], ii[k]) * inv;
                if l == Complex64::new(0.0, 0.0) {
                    continue;
                }
                axpy_neg(&mut ri[start..], &mut ii[start..], l, rk, ik);
            }
        }
        // back substitution on the right-hand sides, column by column of U
        for i in (0..n).rev() {
            let inv = Complex64::new(re[i * stride + i], im[i * stride + i]).inv();
            let (re_head, re_tail) = re.split_at_mut(i * stride);
            let (im_head, im_tail) = im.split_at_mut(i * stride);
            let (ri, ii) = (&mut re_tail[rhs..stride], &mut im_tail[rhs..stride]);
            for (r, m) in ri.iter_mut().zip(ii.iter_mut()) {
                let x = Complex64::new(*r, *m) * inv;
                *r = x.re;
                *m = x.im;
            }
            for (rj, ij) in re_head
                .chunks_exact_mut(stride)
                .zip(im_head.chunks_exact_mut(stride))
            {
                let u = Complex64::new(rj[i], ij[i]);
                axpy_neg(&mut rj[rhs..], &mut ij[rhs..], u, ri, ii);
            }
        }
        true
    }
}

/// Swaps rows `a` and `b` (`a < b`) of the row-major `values`.
fn swap_rows(values: &mut [f64], stride: usize, a: usize, b: usize) {
    let (top, bottom) = values.split_at_mut(b * stride);
    top[a * stride..(a + 1) * stride].swap_with_slice(&mut bottom[..stride]);
}

/// `x -= l y` on whole groups of [`LANES`] (real and imaginary parts apart; each part's
/// group computed as one, so that it maps onto vector registers).
#[inline(always)]
fn axpy_neg(xr: &mut [f64], xi: &mut [f64], l: Complex64, yr: &[f64], yi: &[f64]) {
    let (lr, li) = (l.re, l.im);
    for (((xr, xi), yr), yi) in xr
        .chunks_exact_mut(LANES)
        .zip(xi.chunks_exact_mut(LANES))
        .zip(yr.chunks_exact(LANES))
        .zip(yi.chunks_exact(LANES))
    {
        let mut nr = [0.0; LANES];
        let mut ni = [0.0; LANES];
        for c in 0..LANES {
            nr[c] = xr[c] - (lr * yr[c] - li * yi[c]);
        }
        for c in 0..LANES {
            ni[c] = xi[c] - (lr * yi[c] + li * yr[c]);
        }
        xr.copy_from_slice(&nr);
        xi.copy_from_slice(&ni);
    }
}

#[cfg(test)]
mod tests {
    use super::super::clu;
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The augmented elimination solves what `clu`'s LU solves, for several sizes and
    /// right-hand sides, including a matrix that needs pivoting (zero leading entry).
    #[test]
    fn solves_like_the_lu() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut c = || Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        for &(n, m) in &[(1, 1), (3, 2), (5, 3), (12, 6), (13, 7)] {
            let mut a: Vec<Complex64> = (0..n * n).map(|_| c()).collect();
            if n > 1 {
                a[0] = Complex64::new(0.0, 0.0);
            }
            let b: Vec<Complex64> = (0..n * m).map(|_| c()).collect();
            let mut lu = a.clone();
            let mut piv = vec![0; n];
            assert!(clu::factor(&mut lu, n, &mut piv));
            let mut x = b.clone();
            clu::solve(&lu, n, &piv, &mut x, m);
            let mut aug = Augmented::new(n, m);
            aug.set_matrix(|i, j| a[i * n + j].re);
            for i in 0..n {
                for j in 0..n {
                    aug.add_a(i, j, Complex64::new(0.0, a[i * n + j].im));
                }
                for j in 0..m {
                    aug.set_b(i, j, b[i * m + j]);
                }
            }
            assert!(aug.solve());
            for i in 0..n {
                for j in 0..m {
                    let d = (aug.x(i, j) - x[i * m + j]).norm();
                    assert!(d < 1e-10 * (1.0 + x[i * m + j].norm()), "{n} {m}: {d}");
                }
            }
        }
    }

    /// The AVX2 build of the elimination and the plain one give the same bits.
    #[test]
    fn every_build_gives_the_same_bits() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let mut aug = Augmented::new(12, 6);
        let a: Vec<f64> = (0..144).map(|_| rng.random_range(-1.0..1.0)).collect();
        aug.set_matrix(|i, j| a[i * 12 + j]);
        for i in 0..12 {
            aug.add_a(i, i, Complex64::new(0.0, rng.random_range(0.1..1.0)));
            for j in 0..6 {
                aug.set_b(i, j, Complex64::new(rng.random_range(-1.0..1.0), 0.5));
            }
        }
        let mut plain = aug.clone();
        assert!(aug.solve());
        assert!(plain.solve_here());
        assert_eq!(aug.re, plain.re);
        assert_eq!(aug.im, plain.im);
    }

    #[test]
    fn a_singular_system_is_reported() {
        let mut aug = Augmented::new(2, 1);
        aug.set_matrix(|_, _| 1.0);
        assert!(!aug.solve());
    }
}

//! A small dense complex LU factorisation in place (partial pivoting), for the model FRF's
//! one solve per line: the dynamic stiffness is 18 x 18 for the paper's robot, and a
//! fit evaluates it at hundreds of lines per pose and step. nalgebra's `lu()` takes the
//! matrix by value (an allocation per line); this works on the caller's buffers.
//! Tested against nalgebra's LU below.

use num_complex::Complex64;

/// Factorises the row-major `n x n` matrix `a` in place into `L U` (unit lower `L` below
/// the diagonal, `U` on and above), with the row permutation in `piv` (`piv[k]` is the row
/// swapped with row `k` at step `k`). Returns `false` when a pivot is exactly zero or not
/// finite (the matrix is singular to working precision).
pub fn factor(a: &mut [Complex64], n: usize, piv: &mut [usize]) -> bool {
    debug_assert_eq!(a.len(), n * n);
    for k in 0..n {
        let p = (k..n)
            .max_by(|&i, &j| a[i * n + k].norm_sqr().total_cmp(&a[j * n + k].norm_sqr()))
            .unwrap_or(k);
        piv[k] = p;
        let pivot = a[p * n + k];
        if !(pivot.norm_sqr() > 0.0 && pivot.norm_sqr().is_finite()) {
            return false;
        }
        if p != k {
            for c in 0..n {
                a.swap(k * n + c, p * n + c);
            }
        }
        let inv = pivot.inv();
        for i in k + 1..n {
            let l = a[i * n + k] * inv;
            a[i * n + k] = l;
            if l == Complex64::new(0.0, 0.0) {
                continue;
            }
            for c in k + 1..n {
                let u = a[k * n + c];
                a[i * n + c] -= l * u;
            }
        }
    }
    true
}

/// Solves `A X = B` in place for the `n x m` row-major right-hand sides `b`, with `lu`
/// and `piv` from [`factor`].
pub fn solve(lu: &[Complex64], n: usize, piv: &[usize], b: &mut [Complex64], m: usize) {
    debug_assert_eq!(b.len(), n * m);
    for (k, &p) in piv.iter().enumerate().take(n) {
        if p != k {
            for c in 0..m {
                b.swap(k * m + c, p * m + c);
            }
        }
    }
    // forward: L y = b (unit diagonal)
    for i in 0..n {
        for k in 0..i {
            let l = lu[i * n + k];
            if l == Complex64::new(0.0, 0.0) {
                continue;
            }
            for c in 0..m {
                let y = b[k * m + c];
                b[i * m + c] -= l * y;
            }
        }
    }
    // backward: U x = y
    for i in (0..n).rev() {
        for k in i + 1..n {
            let u = lu[i * n + k];
            for c in 0..m {
                let x = b[k * m + c];
                b[i * m + c] -= u * x;
            }
        }
        let inv = lu[i * n + i].inv();
        for c in 0..m {
            b[i * m + c] *= inv;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};

    fn random(rng: &mut rand::rngs::StdRng, n: usize, m: usize) -> Vec<Complex64> {
        (0..n * m)
            .map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
            .collect()
    }

    /// The in-place LU solves what nalgebra's LU solves, for several sizes and right-hand
    /// sides, including a matrix that needs pivoting (zero leading entry).
    #[test]
    fn solves_like_nalgebra() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(17);
        for &(n, m) in &[(1, 1), (3, 2), (6, 6), (18, 6)] {
            let mut a = random(&mut rng, n, n);
            if n > 1 {
                a[0] = Complex64::new(0.0, 0.0);
            }
            let b = random(&mut rng, n, m);
            let reference = DMatrix::from_row_slice(n, n, &a)
                .lu()
                .solve(&DMatrix::from_row_slice(n, m, &b))
                .unwrap();
            let mut lu = a.clone();
            let mut piv = vec![0; n];
            assert!(factor(&mut lu, n, &mut piv));
            let mut x = b.clone();
            solve(&lu, n, &piv, &mut x, m);
            for i in 0..n {
                for c in 0..m {
                    let d = (x[i * m + c] - reference[(i, c)]).norm();
                    assert!(d < 1e-10 * (1.0 + reference[(i, c)].norm()), "{n} {m}: {d}");
                }
            }
        }
    }

    #[test]
    fn a_singular_matrix_is_reported() {
        let mut a = vec![Complex64::new(1.0, 0.0); 4];
        let mut piv = [0; 2];
        assert!(!factor(&mut a, 2, &mut piv));
    }
}

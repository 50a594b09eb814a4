//! A small dense complex LU factorisation in place (partial pivoting), for the model FRF's
//! one solve per line: the dynamic stiffness is 18 x 18 for the paper's robot, and a
//! fit evaluates it at hundreds of lines per pose and step. nalgebra's `lu()` takes the
//! matrix by value (an allocation per line); this works on the caller's buffers.
//! Tested against nalgebra's LU below.

use num_complex::Complex64;

/// Factorises the row-major `n x n` matrix `a` in place into `L U` (unit lower `L` below
/// the diagonal, `U` on and above), with the row permutation in `piv` (`piv[k]` is the row
/// swapped with row `k` at step `k`). Returns `false` when a pivot is exactly zero or not
/// finite (the matrix is singular to working precision). The inner loops run over row
/// slices (no index checks per element).
pub fn factor(a: &mut [Complex64], n: usize, piv: &mut [usize]) -> bool {
    assert!(a.len() == n * n && piv.len() >= n);
    for k in 0..n {
        // the largest magnitude in column k on and below the diagonal (a NaN wins)
        let mut p = k;
        let mut best = a[k * n + k].norm_sqr();
        for i in k + 1..n {
            let v = a[i * n + k].norm_sqr();
            if v > best || v.is_nan() {
                best = v;
                p = i;
                if v.is_nan() {
                    break;
                }
            }
        }
        piv[k] = p;
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        if p != k {
            let (top, bottom) = a.split_at_mut(p * n);
            top[k * n..(k + 1) * n].swap_with_slice(&mut bottom[..n]);
        }
        let inv = a[k * n + k].inv();
        let (top, rest) = a.split_at_mut((k + 1) * n);
        let urow = &top[k * n + k + 1..(k + 1) * n];
        for row in rest.chunks_exact_mut(n) {
            let l = row[k] * inv;
            row[k] = l;
            if l == Complex64::new(0.0, 0.0) {
                continue;
            }
            for (x, u) in row[k + 1..].iter_mut().zip(urow) {
                *x -= l * *u;
            }
        }
    }
    true
}

/// Solves `A X = B` in place for the `n x m` row-major right-hand sides `b`, with `lu`
/// and `piv` from [`factor`].
pub fn solve(lu: &[Complex64], n: usize, piv: &[usize], b: &mut [Complex64], m: usize) {
    assert!(b.len() == n * m && lu.len() == n * n && piv.len() >= n);
    if m == 0 {
        return;
    }
    for (k, &p) in piv.iter().enumerate().take(n) {
        if p != k {
            let (top, bottom) = b.split_at_mut(p * m);
            top[k * m..(k + 1) * m].swap_with_slice(&mut bottom[..m]);
        }
    }
    // Both sweeps update whole rows of `b` by multiples of another row (right-looking:
    // the row just finished goes into every row after it), so that no row is written
    // twice in a row and the updates pipeline.
    // forward: L y = b (unit diagonal)
    for k in 0..n {
        let (done, rest) = b.split_at_mut((k + 1) * m);
        let bk = &done[k * m..];
        for (i, bi) in (k + 1..n).zip(rest.chunks_exact_mut(m)) {
            let l = lu[i * n + k];
            if l == Complex64::new(0.0, 0.0) {
                continue;
            }
            for (x, y) in bi.iter_mut().zip(bk) {
                *x -= l * *y;
            }
        }
    }
    // backward: U x = y
    for i in (0..n).rev() {
        let (head, tail) = b.split_at_mut(i * m);
        let bi = &mut tail[..m];
        let inv = lu[i * n + i].inv();
        for x in bi.iter_mut() {
            *x *= inv;
        }
        for (j, bj) in head.chunks_exact_mut(m).enumerate() {
            let u = lu[j * n + i];
            for (x, y) in bj.iter_mut().zip(bi.iter()) {
                *x -= u * *y;
            }
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

//! Eigenvalues of a real square matrix with a bounded iteration count.
//!
//! nalgebra's `Matrix::schur()` iterates until it converges, with no limit: on a matrix
//! whose entries span hundreds of decades (an optimiser's wild trial step: an inertia of
//! 1e-202 kg m² beside a stiffness of 1e200 N m/rad) it never does, and the caller hangs.
//! [`eigenvalues`] bounds the QR iterations and says so instead.

use nalgebra::DMatrix;
use num_complex::Complex64;

/// QR iterations allowed per row of the matrix (a well-scaled matrix needs 2-4).
const ITERATIONS_PER_ROW: usize = 200;

/// The eigenvalues of `a`, or `None` when `a` holds a non-finite entry or the Schur
/// iteration does not converge within `ITERATIONS_PER_ROW` times its size.
pub(crate) fn eigenvalues(a: &DMatrix<f64>) -> Option<Vec<Complex64>> {
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let limit = ITERATIONS_PER_ROW * a.nrows().max(1);
    let schur = nalgebra::linalg::Schur::try_new(a.clone(), f64::EPSILON, limit)?;
    Some(schur.complex_eigenvalues().iter().copied().collect())
}

/// An upper bound of the spectral radius of `a`: its largest absolute row sum (Gershgorin).
pub(crate) fn spectral_radius_bound(a: &DMatrix<f64>) -> f64 {
    a.row_iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rotation-plus-scaling matrix with known eigenvalues `s ± i w`.
    #[test]
    fn eigenvalues_of_a_known_matrix() {
        let (s, w) = (-0.5, 3.0);
        let a = DMatrix::from_row_slice(3, 3, &[s, -w, 0.0, w, s, 0.0, 0.0, 0.0, 2.0]);
        let mut ev = eigenvalues(&a).unwrap();
        ev.sort_by(|a, b| a.im.total_cmp(&b.im));
        let want = [
            Complex64::new(s, -w),
            Complex64::new(2.0, 0.0),
            Complex64::new(s, w),
        ];
        for (g, w) in ev.iter().zip(want) {
            assert!((g - w).norm() < 1e-12, "{g} vs {w}");
        }
        assert!(spectral_radius_bound(&a) >= 3.5 - 1e-12);
    }

    #[test]
    fn non_finite_entries_give_none() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, f64::NAN, 0.0, 1.0]);
        assert!(eigenvalues(&a).is_none());
    }
}

//! The covariance of a least-squares estimate from its information matrix `JᵀJ`, honest
//! about directions the data do not determine.
//!
//! A pseudo-inverse drops the directions whose eigenvalues are (numerically) zero and so
//! gives the parameters along them **zero** variance: a gravity term fitted to a plant
//! without gravity sat at `m g l = 4.9e-10 +- 9.4e-28` N m, "5e17 sigma", and was named.
//! Here every eigenvalue is floored at the matrix's numerical precision,
//! `λ_max · n · ε` (the rank threshold of an `n x n` matrix in double precision), so a
//! direction the data do not see gets a variance of at least `1 / (λ_max n ε)`: a
//! parameter along it is reported not identifiable, never certain.

use nalgebra::DMatrix;

/// `(JᵀJ)⁻¹` of a symmetric positive semi-definite information matrix `a`: its Cholesky
/// inverse when it is positive definite, else the inverse with every eigenvalue floored
/// at `λ_max · n · ε` (see the module). All entries infinite when `a` holds no
/// information at all (or non-finite entries).
pub fn covariance_of_information(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let unknown = || DMatrix::from_element(n, a.ncols(), f64::INFINITY);
    if n == 0 || !a.iter().all(|v| v.is_finite()) {
        return unknown();
    }
    if let Some(ch) = a.clone().cholesky() {
        let inv = ch.inverse();
        if inv.iter().all(|v| v.is_finite()) {
            return inv;
        }
    }
    let eig = a.clone().symmetric_eigen();
    let lmax = eig.eigenvalues.max();
    if !(lmax > 0.0) {
        return unknown();
    }
    let floor = lmax * n as f64 * f64::EPSILON;
    let inv_l = eig.eigenvalues.map(|l| 1.0 / l.max(floor));
    let v = &eig.eigenvectors;
    v * DMatrix::from_diagonal(&inv_l) * v.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A well-conditioned matrix: the inverse.
    #[test]
    fn a_regular_information_matrix_is_inverted() {
        let j = DMatrix::from_row_slice(4, 2, &[1.0, 0.5, 0.2, 2.0, -1.0, 0.3, 0.7, 0.1]);
        let a = j.transpose() * &j;
        let want = a.clone().try_inverse().unwrap();
        let got = covariance_of_information(&a);
        assert!((got - want).norm() < 1e-12);
    }

    /// A parameter the residuals do not depend on (a zero column of J, and one along a
    /// combination of two): not identifiable, its variance at least `1/(λ_max n ε)`, where
    /// a pseudo-inverse said 0. The determined parameter keeps its variance.
    #[test]
    fn an_undetermined_direction_gets_a_huge_variance_not_zero() {
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 2.0, 0.0, -1.0, 0.0]);
        let a = j.transpose() * &j;
        let pinv = a.clone().pseudo_inverse(1e-12).unwrap();
        assert_eq!(pinv[(1, 1)], 0.0, "the pseudo-inverse's zero variance");
        let cov = covariance_of_information(&a);
        let lmax = 6.0;
        assert!(
            cov[(1, 1)] >= 0.99 / (lmax * 2.0 * f64::EPSILON),
            "{}",
            cov[(1, 1)]
        );
        assert!((cov[(0, 0)] - 1.0 / 6.0).abs() < 1e-12);
        // two parameters that only act through their sum: the sum is determined, the
        // difference is not
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 1.0, 2.0, 2.0, 0.5, 0.5]);
        let cov = covariance_of_information(&(j.transpose() * &j));
        assert!(cov[(0, 0)] > 1e12 && cov[(1, 1)] > 1e12);
        // (summed from entries near 1e14: the cancellation leaves about 1e14 * 1e-16)
        let sum_var = cov[(0, 0)] + cov[(1, 1)] + 2.0 * cov[(0, 1)];
        assert!((sum_var - 1.0 / 5.25).abs() < 0.05 / 5.25, "{sum_var}");
    }

    /// No information at all, or a NaN: every variance infinite.
    #[test]
    fn no_information_is_infinite_variance() {
        assert!(covariance_of_information(&DMatrix::zeros(2, 2))
            .iter()
            .all(|v| v.is_infinite()));
        let mut a = DMatrix::identity(2, 2);
        a[(0, 1)] = f64::NAN;
        assert!(covariance_of_information(&a)
            .iter()
            .all(|v| v.is_infinite()));
    }
}

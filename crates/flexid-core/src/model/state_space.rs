use super::Chain;
use nalgebra::{DMatrix, DVector};

/// Continuous-time state space of a chain: `x' = A x + B T`, state
/// `x = [theta_1..theta_n, omega_1..omega_n]` [rad, rad/s], input motor torque `T` [N m].
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    /// `2n x 2n` system matrix.
    pub a: DMatrix<f64>,
    /// `2n` input vector (torque on body 1).
    pub b: DVector<f64>,
}

/// Zero-order-hold discretisation `x[k+1] = Ad x[k] + Bd T[k]` with the torque held
/// constant over each sample interval.
#[derive(Debug, Clone, PartialEq)]
pub struct DiscreteStateSpace {
    pub ad: DMatrix<f64>,
    pub bd: DVector<f64>,
    /// Sample interval [s].
    pub ts: f64,
}

impl StateSpace {
    /// Build `A = [[0, I], [-J^-1 C, -J^-1 D]]`, `B = [0; e1/J1]` with `C`, `D` the chain's
    /// tridiagonal stiffness and damping matrices.
    pub fn of(chain: &Chain) -> Self {
        let n = chain.masses();
        let mut a = DMatrix::<f64>::zeros(2 * n, 2 * n);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
        }
        for (i, (&c, &d)) in chain
            .stiffness_nm_per_rad
            .iter()
            .zip(&chain.damping_nms_per_rad)
            .enumerate()
        {
            // coupling between bodies i and i+1: torque on i is c (th_{i+1} - th_i) + d (...)
            for (row, sign) in [(i, 1.0), (i + 1, -1.0)] {
                let jr = chain.inertia_kgm2[row];
                a[(n + row, i)] -= sign * c / jr;
                a[(n + row, i + 1)] += sign * c / jr;
                a[(n + row, n + i)] -= sign * d / jr;
                a[(n + row, n + i + 1)] += sign * d / jr;
            }
        }
        let mut b = DVector::<f64>::zeros(2 * n);
        b[n] = 1.0 / chain.inertia_kgm2[0];
        StateSpace { a, b }
    }

    /// Exact ZOH discretisation at sample interval `ts` [s] through the matrix exponential of
    /// the augmented matrix `[[A, B], [0, 0]] ts` (valid for singular `A`, as a free chain's is).
    pub fn discretize(&self, ts: f64) -> DiscreteStateSpace {
        let m = self.a.nrows();
        let mut aug = DMatrix::<f64>::zeros(m + 1, m + 1);
        aug.view_mut((0, 0), (m, m)).copy_from(&(&self.a * ts));
        aug.view_mut((0, m), (m, 1)).copy_from(&(&self.b * ts));
        let e = aug.exp();
        DiscreteStateSpace {
            ad: e.view((0, 0), (m, m)).into_owned(),
            bd: e.view((0, m), (m, 1)).column(0).into_owned(),
            ts,
        }
    }
}

use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// Errors of the model layer.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    #[error("a chain needs at least one body, got {masses}")]
    NoBodies { masses: usize },
    #[error("{what} has {got} entries, expected {expected}")]
    Length {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("{what}[{index}] = {value} must be positive and finite")]
    NotPositive {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error("{what}[{index}] = {value} must be non-negative and finite")]
    Negative {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error("sample rate {fs_hz} Hz must be positive and finite")]
    SampleRate { fs_hz: f64 },
    #[error("the chain's modes could not be resolved ({detail})")]
    Modes { detail: String },
}

/// An n-mass chain: inertias `J1` (motor) .. `Jn`, spring `c_i` and viscous damper `d_i`
/// between bodies `i` and `i+1`. Free at both ends (no spring or damper to ground), so the
/// motor mobility behaves like `1/(J s)` with `J = sum(J_i)` at low frequency.
///
/// Sign convention: the motor torque acts on body 1 and positive torque accelerates it in
/// the positive direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Chain {
    /// `J1..Jn` [kg m^2], motor first.
    pub inertia_kgm2: Vec<f64>,
    /// `c1..c(n-1)` [N m/rad]: `c_i` joins bodies `i` and `i+1`.
    pub stiffness_nm_per_rad: Vec<f64>,
    /// `d1..d(n-1)` [N m s/rad], in parallel with the springs.
    pub damping_nms_per_rad: Vec<f64>,
}

impl Chain {
    /// A chain from its parameters, validated.
    pub fn new(
        inertia_kgm2: Vec<f64>,
        stiffness_nm_per_rad: Vec<f64>,
        damping_nms_per_rad: Vec<f64>,
    ) -> Result<Self, ModelError> {
        let c = Chain {
            inertia_kgm2,
            stiffness_nm_per_rad,
            damping_nms_per_rad,
        };
        c.validate()?;
        Ok(c)
    }

    /// Check lengths and signs: inertias and stiffnesses positive, dampings non-negative.
    pub fn validate(&self) -> Result<(), ModelError> {
        let n = self.inertia_kgm2.len();
        if n == 0 {
            return Err(ModelError::NoBodies { masses: 0 });
        }
        for (what, v) in [
            ("stiffness_nm_per_rad", &self.stiffness_nm_per_rad),
            ("damping_nms_per_rad", &self.damping_nms_per_rad),
        ] {
            if v.len() != n - 1 {
                return Err(ModelError::Length {
                    what,
                    expected: n - 1,
                    got: v.len(),
                });
            }
        }
        for (what, v) in [
            ("inertia_kgm2", &self.inertia_kgm2),
            ("stiffness_nm_per_rad", &self.stiffness_nm_per_rad),
        ] {
            for (index, &value) in v.iter().enumerate() {
                if !(value.is_finite() && value > 0.0) {
                    return Err(ModelError::NotPositive { what, index, value });
                }
            }
        }
        for (index, &value) in self.damping_nms_per_rad.iter().enumerate() {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ModelError::Negative {
                    what: "damping_nms_per_rad",
                    index,
                    value,
                });
            }
        }
        Ok(())
    }

    /// Number of bodies.
    pub fn masses(&self) -> usize {
        self.inertia_kgm2.len()
    }

    /// Total inertia `J = J1 + .. + Jn` [kg m^2].
    pub fn total_inertia(&self) -> f64 {
        self.inertia_kgm2.iter().sum()
    }

    /// Driving-point impedance `Z(s) = T(s) / V1(s)` [N m s/rad] at complex `s` [rad/s],
    /// evaluated as the ladder (continued fraction) from the far end:
    /// `Z_n = J_n s`, `Z_i = J_i s + 1 / (1/(d_i + c_i/s) + 1/Z_{i+1})`.
    pub fn impedance(&self, s: Complex64) -> Complex64 {
        self.impedance_and_derivative(s).0
    }

    /// `Z(s)` and `dZ/ds` (forward-mode differentiation of the ladder).
    pub fn impedance_and_derivative(&self, s: Complex64) -> (Complex64, Complex64) {
        let n = self.masses();
        let mut z = s * self.inertia_kgm2[n - 1];
        let mut dz = Complex64::new(self.inertia_kgm2[n - 1], 0.0);
        for i in (0..n - 1).rev() {
            let c = self.stiffness_nm_per_rad[i];
            let d = self.damping_nms_per_rad[i];
            // coupling impedance k = d + c/s (torque per relative velocity)
            let k = d + c / s;
            let dk = -c / (s * s);
            // series: q = 1 / (1/k + 1/z) = k z / (k + z)
            let den = k + z;
            let q = k * z / den;
            let dq = (dk * z * z + dz * k * k) / (den * den);
            z = s * self.inertia_kgm2[i] + q;
            dz = dq + self.inertia_kgm2[i];
        }
        (z, dz)
    }

    /// Continuous-time motor mobility `H(jw) = V1/T` [(rad/s)/(N m)] at `f_hz`.
    pub fn mobility(&self, f_hz: f64) -> Complex64 {
        let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f_hz);
        1.0 / self.impedance(s)
    }

    /// Undamped resonance frequencies [Hz] of the free chain (the n-1 non-zero modes),
    /// ascending: the peaks of the motor mobility.
    pub fn resonances_hz(&self) -> Vec<f64> {
        undamped_modes(&self.inertia_kgm2, &self.stiffness_nm_per_rad, false)
    }

    /// Undamped anti-resonance frequencies [Hz], ascending: the modes of the chain with the
    /// motor (body 1) locked, i.e. the notches of the motor mobility.
    pub fn antiresonances_hz(&self) -> Vec<f64> {
        undamped_modes(&self.inertia_kgm2, &self.stiffness_nm_per_rad, true)
    }
}

/// Undamped modal frequencies [Hz] of the chain's stiffness/inertia problem, ascending.
/// `motor_locked`: body 1 held fixed (its spring `c1` then grounds body 2).
fn undamped_modes(j: &[f64], c: &[f64], motor_locked: bool) -> Vec<f64> {
    let n = j.len();
    let first = usize::from(motor_locked);
    let m = n - first;
    if m == 0 || (n == 1) {
        return Vec::new();
    }
    // Stiffness matrix of the free chain, restricted to bodies first..n.
    let mut k = nalgebra::DMatrix::<f64>::zeros(m, m);
    for (i, &ci) in c.iter().enumerate() {
        // spring between body i and i+1
        for (a, b, sign) in [
            (i, i, 1.0),
            (i + 1, i + 1, 1.0),
            (i, i + 1, -1.0),
            (i + 1, i, -1.0),
        ] {
            if a >= first && b >= first {
                k[(a - first, b - first)] += sign * ci;
            }
        }
    }
    // Mass-normalised: M^{-1/2} K M^{-1/2}, symmetric.
    for a in 0..m {
        for b in 0..m {
            k[(a, b)] /= (j[a + first] * j[b + first]).sqrt();
        }
    }
    let eig = nalgebra::SymmetricEigen::new(k);
    let mut w2: Vec<f64> = eig.eigenvalues.iter().copied().collect();
    w2.sort_by(|a, b| a.total_cmp(b));
    if !motor_locked {
        // drop the rigid-body mode (eigenvalue 0)
        w2.remove(0);
    }
    w2.iter()
        .map(|&x| x.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
        .collect()
}

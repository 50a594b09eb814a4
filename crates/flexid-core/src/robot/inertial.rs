//! The algebra of [`Inertial`]: re-expression in another frame and the combination of two
//! bodies into one (parallel-axis theorem).

use nalgebra::{Isometry3, Matrix3, Vector3};

use super::Inertial;

impl Inertial {
    /// No mass: a massless link [kg, m, kg m^2 all zero].
    pub fn zero() -> Self {
        Inertial {
            mass_kg: 0.0,
            com_m: Vector3::zeros(),
            inertia_kgm2: Matrix3::zeros(),
        }
    }

    /// The same body expressed in the parent frame, `frame` being this frame's pose in the
    /// parent [m, rad]: the centre of mass mapped, the inertia tensor rotated
    /// (`R I R^T`, still about the centre of mass).
    pub fn transformed(&self, frame: &Isometry3<f64>) -> Self {
        let r = frame.rotation.to_rotation_matrix();
        Inertial {
            mass_kg: self.mass_kg,
            com_m: frame.transform_point(&self.com_m.into()).coords,
            inertia_kgm2: r.matrix() * self.inertia_kgm2 * r.matrix().transpose(),
        }
    }

    /// The two bodies rigidly joined, both given in the same frame: masses added, centre of
    /// mass the mass-weighted mean, inertia about the joint centre of mass by the
    /// parallel-axis theorem. Two massless bodies give a massless body at the origin whose
    /// inertia is the sum of theirs.
    pub fn combined(&self, other: &Inertial) -> Self {
        let mass_kg = self.mass_kg + other.mass_kg;
        if mass_kg <= 0.0 {
            return Inertial {
                mass_kg,
                com_m: Vector3::zeros(),
                inertia_kgm2: self.inertia_kgm2 + other.inertia_kgm2,
            };
        }
        let com_m = (self.com_m * self.mass_kg + other.com_m * other.mass_kg) / mass_kg;
        Inertial {
            mass_kg,
            com_m,
            inertia_kgm2: self.inertia_about(&com_m) + other.inertia_about(&com_m),
        }
    }

    /// Inertia tensor about the point `p` (same frame), parallel axes [kg m^2]:
    /// `I_c + m (|d|^2 E - d d^T)`, d = c - p.
    pub fn inertia_about(&self, p: &Vector3<f64>) -> Matrix3<f64> {
        let d = self.com_m - p;
        self.inertia_kgm2
            + (Matrix3::identity() * d.norm_squared() - d * d.transpose()) * self.mass_kg
    }

    /// Why these mass properties are not physical, if they are not: a negative or
    /// non-finite mass, non-finite numbers, an asymmetric tensor, a negative principal
    /// moment or one that breaks the triangle inequality (`I1 + I2 >= I3`), each to a
    /// relative tolerance of 1e-9 of the largest moment.
    pub fn unphysical(&self) -> Option<String> {
        if !self.mass_kg.is_finite() || self.mass_kg < 0.0 {
            return Some(format!("mass {} kg", self.mass_kg));
        }
        if !self
            .com_m
            .iter()
            .chain(self.inertia_kgm2.iter())
            .all(|x| x.is_finite())
        {
            return Some("non-finite centre of mass or inertia".into());
        }
        let i = &self.inertia_kgm2;
        let scale = i.amax().max(f64::MIN_POSITIVE);
        if (i - i.transpose()).amax() > 1e-9 * scale {
            return Some("asymmetric inertia tensor".into());
        }
        let p = i.symmetric_eigenvalues();
        let tol = 1e-9 * scale;
        if p.min() < -tol {
            return Some(format!("negative principal moment {:e} kg m^2", p.min()));
        }
        let sum = p.sum();
        if p.iter().any(|&pk| 2.0 * pk > sum + tol) {
            return Some(format!(
                "principal moments {:?} kg m^2 break the triangle inequality",
                p.as_slice()
            ));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A box of mass m and sides a, b, c centred at `at`.
    fn cuboid(m: f64, [a, b, c]: [f64; 3], at: Vector3<f64>) -> Inertial {
        Inertial {
            mass_kg: m,
            com_m: at,
            inertia_kgm2: Matrix3::from_diagonal(&Vector3::new(
                m * (b * b + c * c) / 12.0,
                m * (a * a + c * c) / 12.0,
                m * (a * a + b * b) / 12.0,
            )),
        }
    }

    #[test]
    fn two_halves_of_a_box_combine_into_the_box() {
        // a 2 x 1 x 1 box of 4 kg from two 1 x 1 x 1 cubes of 2 kg at x = -0.5 and +0.5
        let left = cuboid(2.0, [1.0, 1.0, 1.0], Vector3::new(-0.5, 0.0, 0.0));
        let right = cuboid(2.0, [1.0, 1.0, 1.0], Vector3::new(0.5, 0.0, 0.0));
        let whole = left.combined(&right);
        let expected = cuboid(4.0, [2.0, 1.0, 1.0], Vector3::zeros());
        assert!((whole.mass_kg - 4.0).abs() < 1e-15);
        assert!(whole.com_m.norm() < 1e-15);
        assert!((whole.inertia_kgm2 - expected.inertia_kgm2).amax() < 1e-14);
    }

    #[test]
    fn re_expression_rotates_the_tensor_and_maps_the_centre() {
        let body = cuboid(3.0, [0.1, 0.2, 0.3], Vector3::new(0.1, 0.0, 0.0));
        let frame = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        );
        let moved = body.transformed(&frame);
        // x of the body is y of the parent: the centre at (1, 2.1, 3), Ixx and Iyy swapped
        assert!((moved.com_m - Vector3::new(1.0, 2.1, 3.0)).norm() < 1e-15);
        let i = body.inertia_kgm2;
        let expected = Matrix3::from_diagonal(&Vector3::new(i[(1, 1)], i[(0, 0)], i[(2, 2)]));
        assert!((moved.inertia_kgm2 - expected).amax() < 1e-15);
    }

    #[test]
    fn a_rod_as_a_thin_disc_breaks_the_triangle_inequality() {
        let ok = cuboid(1.0, [1.0, 0.1, 0.1], Vector3::zeros());
        assert_eq!(ok.unphysical(), None);
        let mut bad = ok;
        bad.inertia_kgm2[(0, 0)] = 1.0;
        assert!(bad.unphysical().unwrap().contains("triangle"));
        bad = ok;
        bad.mass_kg = -1.0;
        assert!(bad.unphysical().is_some());
    }
}

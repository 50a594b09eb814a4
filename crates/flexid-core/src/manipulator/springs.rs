//! The spring-damper pairs of the flexible manipulator and the parameter vector `theta`.
//!
//! A gear pair joins joint `i`'s arm coordinate and motor `i` (arm side); its torque is
//! `k_g (q_a - q_m) + c_g (v_a - v_m)`. A bearing pair holds one bearing coordinate (a
//! small rotation about an axis orthogonal to the joint's, inserted right after the joint
//! in the kinematic chain) to zero: `k_b q_b + c_b v_b`. Each pair enters the linearised
//! stiffness and damping matrices as `k e e^T` and `c e e^T`, with `e` the difference of
//! the coordinates it joins: the form the FRF's derivatives use.

use serde::{Deserialize, Serialize};

/// Which axis of a bearing pair (the two are orthogonal to each other and to the joint's).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BearingAxis {
    /// About the link frame's x axis.
    X,
    /// About the link frame's y axis.
    Y,
    /// About the link frame's z axis.
    Z,
}

impl BearingAxis {
    /// `x`, `y` or `z`.
    pub fn letter(self) -> char {
        match self {
            BearingAxis::X => 'x',
            BearingAxis::Y => 'y',
            BearingAxis::Z => 'z',
        }
    }
}

/// What a spring-damper pair joins.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SpringKind {
    /// The gear of joint `joint` (0-based): its arm coordinate to its motor.
    Gear { joint: usize },
    /// A bearing flexibility after joint `joint` (0-based) about `axis`.
    Bearing { joint: usize, axis: BearingAxis },
}

/// One spring-damper pair with the coordinate(s) it acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Spring {
    /// What it joins.
    pub kind: SpringKind,
    /// Its arm coordinate (the joint's, or the bearing's), an index into the arm's
    /// coordinates of [`super::RigidPose`].
    pub arm_coord: usize,
}

impl Spring {
    /// The parameter's name after the paper's eq. (5), joints 1-based: `k_g3`, `k_b1x`
    /// (`prefix` `k` for the stiffness, `c` for the damping).
    pub fn name(&self, prefix: char) -> String {
        match self.kind {
            SpringKind::Gear { joint } => format!("{prefix}_g{}", joint + 1),
            SpringKind::Bearing { joint, axis } => {
                format!("{prefix}_b{}{}", joint + 1, axis.letter())
            }
        }
    }
}

/// The spring-damper parameters `theta`, one stiffness and one damping per pair of
/// [`super::RigidPose::springs`], in that order (the paper's eq. (5) lists the bearing
/// pairs first, then the gears; the order here is the pose's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Flexibilities {
    /// Stiffness of each pair [N m/rad], arm side.
    pub stiffness_nm_per_rad: Vec<f64>,
    /// Viscous damping of each pair [N m s/rad], arm side.
    pub damping_nms_per_rad: Vec<f64>,
}

impl Flexibilities {
    /// Every value times its own factor `exp(u ln(1 + d))`, `u` uniform in `[-1, 1]` drawn
    /// from `seed` (so within `[1/(1+d), 1+d]`): a simulated robot that deviates from its
    /// data sheet as a real one does. `d = 0` gives the values unchanged.
    pub fn deviated(&self, d: f64, seed: u64) -> Flexibilities {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0b0b_5eed);
        let mut f = |v: &f64| v * ((1.0 + d).ln() * rng.random_range(-1.0..=1.0)).exp();
        Flexibilities {
            stiffness_nm_per_rad: self.stiffness_nm_per_rad.iter().map(&mut f).collect(),
            damping_nms_per_rad: self.damping_nms_per_rad.iter().map(&mut f).collect(),
        }
    }

    /// Validated: as many dampings as stiffnesses, stiffnesses positive, dampings
    /// non-negative, all finite.
    pub fn new(
        stiffness_nm_per_rad: Vec<f64>,
        damping_nms_per_rad: Vec<f64>,
    ) -> Result<Self, super::ManipulatorError> {
        use super::ManipulatorError as E;
        if damping_nms_per_rad.len() != stiffness_nm_per_rad.len() {
            return Err(E::Length {
                what: "damping_nms_per_rad",
                expected: stiffness_nm_per_rad.len(),
                got: damping_nms_per_rad.len(),
            });
        }
        for (index, &value) in stiffness_nm_per_rad.iter().enumerate() {
            if !(value.is_finite() && value > 0.0) {
                return Err(E::NotPositive {
                    what: "stiffness_nm_per_rad",
                    index,
                    value,
                });
            }
        }
        for (index, &value) in damping_nms_per_rad.iter().enumerate() {
            if !(value.is_finite() && value >= 0.0) {
                return Err(E::Negative {
                    what: "damping_nms_per_rad",
                    index,
                    value,
                });
            }
        }
        Ok(Flexibilities {
            stiffness_nm_per_rad,
            damping_nms_per_rad,
        })
    }

    /// Number of pairs.
    pub fn pairs(&self) -> usize {
        self.stiffness_nm_per_rad.len()
    }

    /// `[ln k_1 .. ln k_S, ln c_1 .. ln c_S]`: the identification's parameters (every one
    /// of order one in scale; a damping of zero is `-inf`, which the identification never
    /// starts from).
    pub fn to_log(&self) -> Vec<f64> {
        self.stiffness_nm_per_rad
            .iter()
            .chain(&self.damping_nms_per_rad)
            .map(|x| x.ln())
            .collect()
    }

    /// The inverse of [`Flexibilities::to_log`].
    pub fn from_log(theta: &[f64]) -> Self {
        let s = theta.len() / 2;
        Flexibilities {
            stiffness_nm_per_rad: theta[..s].iter().map(|x| x.exp()).collect(),
            damping_nms_per_rad: theta[s..].iter().map(|x| x.exp()).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_the_paper() {
        let g = Spring {
            kind: SpringKind::Gear { joint: 2 },
            arm_coord: 7,
        };
        let b = Spring {
            kind: SpringKind::Bearing {
                joint: 0,
                axis: BearingAxis::X,
            },
            arm_coord: 1,
        };
        assert_eq!(g.name('k'), "k_g3");
        assert_eq!(b.name('c'), "c_b1x");
    }

    #[test]
    fn flexibilities_are_validated_and_round_trip_through_logs() {
        assert!(Flexibilities::new(vec![1e5, -1.0], vec![1.0, 1.0]).is_err());
        assert!(Flexibilities::new(vec![1e5], vec![1.0, 1.0]).is_err());
        assert!(Flexibilities::new(vec![1e5], vec![-1.0]).is_err());
        let f = Flexibilities::new(vec![1e5, 3e6], vec![20.0, 0.5]).unwrap();
        let back = Flexibilities::from_log(&f.to_log());
        for (a, b) in back
            .stiffness_nm_per_rad
            .iter()
            .zip(&f.stiffness_nm_per_rad)
        {
            assert!((a / b - 1.0).abs() < 1e-14);
        }
        for (a, b) in back.damping_nms_per_rad.iter().zip(&f.damping_nms_per_rad) {
            assert!((a / b - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn deviations_stay_within_their_bound_and_differ() {
        let r = crate::manipulator::reference::robot();
        let d = r.nominal.deviated(0.3, 7);
        let mut ratios = Vec::new();
        for (a, b) in d
            .stiffness_nm_per_rad
            .iter()
            .zip(&r.nominal.stiffness_nm_per_rad)
        {
            let x = a / b;
            assert!((1.0 / 1.3 - 1e-12..=1.3 + 1e-12).contains(&x), "{x}");
            ratios.push(x);
        }
        assert!(ratios.iter().any(|x| (x - 1.0).abs() > 0.05));
        assert_eq!(r.nominal.deviated(0.3, 7), d, "seeded");
        assert_eq!(r.nominal.deviated(0.0, 7), r.nominal);
    }
}

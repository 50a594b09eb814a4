//! An identified chain against the chain it was simulated from: the relative error of each
//! inertia and stiffness, as the demo prints it and the end-to-end tests assert it.

use super::Chain;
use std::fmt;

/// One identified parameter next to its true value.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamError {
    /// `J1`, `J2`, ... (kg m^2) or `c1`, ... (N m/rad).
    pub name: String,
    pub identified: f64,
    pub truth: f64,
}

impl ParamError {
    /// (identified - true) / true.
    pub fn relative(&self) -> f64 {
        (self.identified - self.truth) / self.truth
    }
}

impl fmt::Display for ParamError {
    /// `J1: identified 1.40865e-3, true 1.40600e-3, error +0.188 %`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: identified {:.5e}, true {:.5e}, error {:+.3} %",
            self.name,
            self.identified,
            self.truth,
            100.0 * self.relative()
        )
    }
}

/// The inertias then the stiffnesses of `identified` against `truth`, given as their
/// vectors (`J`, `c`); `None` when the numbers of bodies differ.
pub fn against_truth(
    identified: (&[f64], &[f64]),
    truth: (&[f64], &[f64]),
) -> Option<Vec<ParamError>> {
    if identified.0.len() != truth.0.len() || identified.1.len() != truth.1.len() {
        return None;
    }
    let mut out = Vec::with_capacity(truth.0.len() + truth.1.len());
    for (name, got, want) in [("J", identified.0, truth.0), ("c", identified.1, truth.1)] {
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            out.push(ParamError {
                name: format!("{name}{}", i + 1),
                identified: *g,
                truth: *w,
            });
        }
    }
    Some(out)
}

impl Chain {
    /// This chain's inertias and stiffnesses against `truth`'s ([`against_truth`]).
    pub fn against_truth(&self, truth: &Chain) -> Option<Vec<ParamError>> {
        against_truth(
            (&self.inertia_kgm2, &self.stiffness_nm_per_rad),
            (&truth.inertia_kgm2, &truth.stiffness_nm_per_rad),
        )
    }
}

/// Panics unless every parameter of `identified` is within `tol` (relative) of `truth`'s
/// and the numbers of bodies agree; prints each line first. For tests.
pub fn assert_within(identified: (&[f64], &[f64]), truth: (&[f64], &[f64]), tol: f64) {
    let errors = against_truth(identified, truth).unwrap_or_else(|| {
        panic!(
            "identified J {:?}, c {:?}; true J {:?}, c {:?}",
            identified.0, identified.1, truth.0, truth.1
        )
    });
    for e in &errors {
        eprintln!("  {e}");
    }
    for e in &errors {
        assert!(
            e.relative().abs() < tol,
            "{e} (tolerance {} %)",
            100.0 * tol
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_are_relative_to_the_truth_and_orders_must_agree() {
        let e = against_truth((&[2.0, 1.0], &[90.0]), (&[1.0, 1.0], &[100.0])).expect("same order");
        assert_eq!(e.len(), 3);
        assert_eq!(e[0].name, "J1");
        assert_eq!(e[0].relative(), 1.0);
        assert_eq!(e[2].name, "c1");
        assert!((e[2].relative() + 0.1).abs() < 1e-15);
        assert_eq!(
            e[2].to_string(),
            "c1: identified 9.00000e1, true 1.00000e2, error -10.000 %"
        );
        assert!(against_truth((&[1.0], &[]), (&[1.0, 1.0], &[1.0])).is_none());
    }

    #[test]
    #[should_panic(expected = "J2")]
    fn a_parameter_outside_the_tolerance_fails() {
        assert_within((&[1.0, 1.1], &[1.0]), (&[1.0, 1.0], &[1.0]), 0.05);
    }
}

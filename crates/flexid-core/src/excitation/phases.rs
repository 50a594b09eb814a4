//! Phase designs for multisines: Schroeder and uniform random phases.

use std::f64::consts::PI;

use rand::Rng;

/// Schroeder phases \[rad\] for lines `lines` (increasing DFT indices) with relative amplitudes
/// `amps` (one per line): the group delay at line `k` is the period times the fraction of
/// power below `k`, i.e. `phi_j = phi_{j-1} - 2 pi (k_j - k_{j-1}) P_{j-1}` with `P` the
/// cumulative normalised power. For a flat band of consecutive lines this is the classical
/// `phi_j = -pi j (j - 1) / F`.
pub(crate) fn schroeder_phases(lines: &[usize], amps: &[f64]) -> Vec<f64> {
    let total: f64 = amps.iter().map(|a| a * a).sum();
    let mut phases = Vec::with_capacity(lines.len());
    let mut phi = 0.0_f64;
    let mut cum = 0.0_f64;
    for (j, (&k, &a)) in lines.iter().zip(amps).enumerate() {
        if j > 0 {
            let dk = (k - lines[j - 1]) as f64;
            phi = (phi - 2.0 * PI * dk * cum / total).rem_euclid(2.0 * PI);
        }
        phases.push(phi);
        cum += a * a;
    }
    phases
}

/// `count` independent phases uniform on `[0, 2 pi)` \[rad\].
pub(crate) fn random_phases<R: Rng>(count: usize, rng: &mut R) -> Vec<f64> {
    (0..count).map(|_| 2.0 * PI * rng.random::<f64>()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schroeder_matches_classical_formula_for_flat_consecutive_lines() {
        let lines: Vec<usize> = (1..=50).collect();
        let amps = vec![1.0; 50];
        let ph = schroeder_phases(&lines, &amps);
        let f = 50.0;
        for (j, p) in ph.iter().enumerate() {
            let jj = (j + 1) as f64;
            let classical = (-PI * jj * (jj - 1.0) / f).rem_euclid(2.0 * PI);
            let d = (p - classical).rem_euclid(2.0 * PI);
            assert!(d.min(2.0 * PI - d) < 1e-9, "line {j}: {p} vs {classical}");
        }
    }
}

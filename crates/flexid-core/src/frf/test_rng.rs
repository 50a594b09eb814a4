//! A tiny deterministic uniform generator for the estimators' Monte Carlo tests (no
//! dependency, the same sequence on every machine).

/// The next uniform number in `[0, 1)` of a 64-bit linear congruential generator (Knuth's
/// MMIX constants), 53 bits of it.
pub(crate) fn lcg(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 53) as f64
}

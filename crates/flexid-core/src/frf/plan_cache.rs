//! Forward real FFT plans kept per thread, by length: a stepped sine's block estimator
//! ([`super::estimate_stepped`]) plans one FFT per dwell block, and the diagnosis's search
//! estimates the simulated response of every candidate with it, hundreds of times over the
//! same block lengths; planning (Rader's algorithm for a prime length among them) took
//! longer than the transforms. Each length is planned by a planner of its own, as the
//! estimators always did: a planner that has planned other lengths may build a length
//! from its cached parts in another way, which transforms differently in the last bits.

use realfft::{RealFftPlanner, RealToComplex};
use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::Arc;

/// Lengths kept per thread before the cache starts afresh (a long-running daemon sees
/// recordings of many period lengths; one diagnosis of a stepped sine, about 40).
const MAX_PLANS: usize = 256;

thread_local! {
    static PLANS: RefCell<HashMap<usize, Arc<dyn RealToComplex<f64>>>> =
        RefCell::new(HashMap::new());
}

/// The forward real FFT of `len` samples, planned once per thread (by a fresh planner:
/// the plan `RealFftPlanner::new().plan_fft_forward(len)` gives).
pub(crate) fn forward(len: usize) -> Arc<dyn RealToComplex<f64>> {
    PLANS.with(|p| {
        let mut p = p.borrow_mut();
        if let Some(f) = p.get(&len) {
            return Arc::clone(f);
        }
        if p.len() >= MAX_PLANS {
            p.clear();
        }
        let f = RealFftPlanner::<f64>::new().plan_fft_forward(len);
        p.insert(len, Arc::clone(&f));
        f
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kept plan transforms to the bit as a freshly planned one, for lengths with
    /// different algorithms (power of two, composite, prime: Rader's), asked for twice,
    /// after other lengths (a planner shared between lengths changed the measured FRF of
    /// a stepped sine in its last bits).
    #[test]
    fn a_kept_plan_equals_a_fresh_one() {
        for len in [64usize, 1998, 7992, 1000, 3996, 4001, 7919, 4001, 3996] {
            let x: Vec<f64> = (0..len)
                .map(|i| ((i as f64 * 12.9898).sin() * 43758.5453).fract())
                .collect();
            let run = |f: &Arc<dyn RealToComplex<f64>>| {
                let mut input = x.clone();
                let mut out = f.make_output_vec();
                f.process(&mut input, &mut out).unwrap();
                out
            };
            let fresh = RealFftPlanner::<f64>::new().plan_fft_forward(len);
            assert_eq!(run(&forward(len)), run(&fresh), "{len}");
        }
    }
}

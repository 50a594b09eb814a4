//! The search's simulated records kept per thread: the search simulates hundreds of
//! candidates over the same levels, each record 10⁵ samples and more a level; written
//! into fresh vectors, every one was fresh memory from the system (a page fault every 512
//! samples, about a sixth of a stepped sine's diagnosis). Kept, the vectors are written
//! again in place.

use super::nlsim::SimOut;
use std::cell::RefCell;

thread_local! {
    static KEPT: RefCell<Vec<SimOut>> = const { RefCell::new(Vec::new()) };
}

/// `f` with this thread's kept outputs (empty the first time; whatever `f` leaves in
/// them is kept for the next call). A nested call gets an empty set of its own.
pub fn with<R>(f: impl FnOnce(&mut Vec<SimOut>) -> R) -> R {
    let mut outs = KEPT.with(|k| std::mem::take(&mut *k.borrow_mut()));
    let r = f(&mut outs);
    KEPT.with(|k| *k.borrow_mut() = outs);
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vectors left by one call are the next call's, with their memory; a nested call
    /// does not see them.
    #[test]
    fn outputs_are_kept_between_calls() {
        let addr = with(|outs| {
            outs.clear();
            outs.push(SimOut {
                pos: vec![1.0; 1000],
                ..SimOut::default()
            });
            with(|inner| assert!(inner.is_empty()));
            outs[0].pos.as_ptr() as usize
        });
        with(|outs| {
            assert_eq!(outs.len(), 1);
            assert_eq!(outs[0].pos.as_ptr() as usize, addr);
        });
    }
}

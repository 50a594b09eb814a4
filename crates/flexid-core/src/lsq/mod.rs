//! Least squares: flexid's one Levenberg-Marquardt ([`lm`]), for the identification's
//! chain fit (analytic normal equations) and the diagnosis's joint refits of the chain
//! with an effect's parameters ([`residuals`]: any residual closure, Jacobian by forward
//! differences).
//!
//! The diagnosis keeps one derivative-free search beside it, the Nelder-Mead simplex of
//! `diagnose::simplex`: the spring nonlinearities (backlash, hardening) are fitted through
//! a time-domain simulation whose cost is not smooth in the gap (contact switches move
//! from sample to sample), where a finite-difference Jacobian is noise.

pub mod information;
pub mod lm;
pub mod residuals;

pub use information::covariance_of_information;
pub use lm::{
    minimize, minimize_until, Damping, LmOptions, LmOutcome, LmWorkspace, NormalEquations,
};
pub use residuals::{minimise, LmResult, MIN_REL_IMPROVEMENT};

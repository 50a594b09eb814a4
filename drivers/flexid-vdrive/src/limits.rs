//! Drive limits and the faults they raise.
//!
//! * Torque: the set-point is **clamped** (never a fault) to the smaller of the peak torque
//!   and 0x6072 max torque; statusword bit 11 (internal limit active) is set while it is.
//! * Speed: `|velocity| > max_speed` at a SYNC sample is a fault, EMCY 0x8400.
//! * Continuous torque (optional, `continuous_torque_nm`): an i²t model,
//!   `x' = ((T/T_cont)^2 - x) / tau`; `x > 1` is a fault, EMCY 0x2310 (continuous over
//!   current).
//! * Heartbeat consumer ([`crate::heartbeat`]): EMCY 0x8130.
//! * SYNC loss ([`crate::sync_watch`]): EMCY 0x8700.
//! * Connection aborted with 0x6007 = 1: EMCY 0x8100.

use canopen_rs::ErrorRegister;

/// Why the drive went to Fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// Motor speed above the maximum.
    Overspeed,
    /// i²t over-current (continuous torque above the limit for too long).
    ContinuousOvercurrent,
    /// The master's heartbeat was not seen within the consumer time.
    HeartbeatLost,
    /// No SYNC for the configured number of cycles in Operation enabled
    /// ([`crate::sync_watch`]).
    SyncLost,
    /// The connection to the master was aborted (NMT Operational left, reset
    /// communication) with 0x6007 = 1 (fault signal).
    ConnectionAborted,
}

impl FaultKind {
    /// Whether it is a communication error (CiA 301 0x1029:1 applies).
    pub const fn is_communication(self) -> bool {
        matches!(self, FaultKind::HeartbeatLost | FaultKind::SyncLost)
    }

    /// The EMCY error code (also 0x603F error code).
    pub const fn emcy_code(self) -> u16 {
        match self {
            FaultKind::Overspeed => 0x8400,
            FaultKind::ContinuousOvercurrent => 0x2310,
            FaultKind::HeartbeatLost => 0x8130,
            // CiA 301 has no code for a missing SYNC; CiA 402 lists 0x8700 "sync
            // controller" in the monitoring class.
            FaultKind::SyncLost => 0x8700,
            FaultKind::ConnectionAborted => 0x8100,
        }
    }

    /// The error register (0x1001) bits (the generic bit 0 is added by the EMCY layer).
    pub const fn error_register(self) -> ErrorRegister {
        ErrorRegister(match self {
            FaultKind::Overspeed => ErrorRegister::DEVICE_PROFILE,
            FaultKind::ContinuousOvercurrent => ErrorRegister::CURRENT,
            FaultKind::HeartbeatLost | FaultKind::SyncLost | FaultKind::ConnectionAborted => {
                ErrorRegister::COMMUNICATION
            }
        })
    }
}

/// Limit parameters, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitConfig {
    /// Peak torque the power stage can produce [N m].
    pub peak_torque_nm: f64,
    /// Maximum motor speed [rad/s]; above it the drive faults.
    pub max_speed_rad_s: f64,
    /// Continuous torque of the i²t monitor [N m]; `None`: no i²t monitor.
    pub continuous_torque_nm: Option<f64>,
    /// Thermal time constant of the i²t monitor [s].
    pub i2t_time_constant_s: f64,
}

/// The limit monitor: clamps torque, watches speed and i²t. No allocation.
#[derive(Debug, Clone)]
pub struct Limiter {
    cfg: LimitConfig,
    i2t: f64,
}

impl Limiter {
    /// A monitor with a cold i²t state.
    pub fn new(cfg: LimitConfig) -> Self {
        Self { cfg, i2t: 0.0 }
    }

    /// The configuration.
    pub fn config(&self) -> &LimitConfig {
        &self.cfg
    }

    /// Clamps `torque_nm` to `min(peak, max_torque_nm)`; returns the torque and whether
    /// it was limited. NaN becomes 0 (limited).
    pub fn clamp(&self, torque_nm: f64, max_torque_nm: f64) -> (f64, bool) {
        let lim = self.cfg.peak_torque_nm.min(max_torque_nm).max(0.0);
        if torque_nm.is_nan() {
            return (0.0, true);
        }
        let t = torque_nm.clamp(-lim, lim);
        (t, t != torque_nm)
    }

    /// Checks a sample's speed; `Some(Overspeed)` above the limit.
    pub fn check_speed(&self, velocity_rad_s: f64) -> Option<FaultKind> {
        (velocity_rad_s.abs() > self.cfg.max_speed_rad_s || velocity_rad_s.is_nan())
            .then_some(FaultKind::Overspeed)
    }

    /// Integrates the i²t model over `dt_s` [s] with the applied `torque_nm`;
    /// `Some(ContinuousOvercurrent)` when it trips.
    pub fn integrate_i2t(&mut self, torque_nm: f64, dt_s: f64) -> Option<FaultKind> {
        let t_cont = self.cfg.continuous_torque_nm?;
        let load = (torque_nm / t_cont).powi(2);
        let a = (-dt_s / self.cfg.i2t_time_constant_s.max(1e-9)).exp();
        self.i2t = load + (self.i2t - load) * a;
        (self.i2t > 1.0).then_some(FaultKind::ContinuousOvercurrent)
    }

    /// The i²t state (1.0 = trip level).
    pub fn i2t(&self) -> f64 {
        self.i2t
    }

    /// Whether the cause of `kind` is gone (fault reset allowed).
    pub fn cleared(&self, kind: FaultKind, velocity_rad_s: f64) -> bool {
        match kind {
            FaultKind::Overspeed => self.check_speed(velocity_rad_s).is_none(),
            FaultKind::ContinuousOvercurrent => self.i2t <= 1.0,
            FaultKind::HeartbeatLost | FaultKind::SyncLost | FaultKind::ConnectionAborted => true,
        }
    }

    /// Cools the i²t state (reset node).
    pub fn reset(&mut self) {
        self.i2t = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lim(cont: Option<f64>) -> Limiter {
        Limiter::new(LimitConfig {
            peak_torque_nm: 3.0,
            max_speed_rad_s: 100.0,
            continuous_torque_nm: cont,
            i2t_time_constant_s: 1.0,
        })
    }

    #[test]
    fn clamps_to_the_smaller_limit() {
        let l = lim(None);
        assert_eq!(l.clamp(5.0, 10.0), (3.0, true));
        assert_eq!(l.clamp(-5.0, 2.0), (-2.0, true));
        assert_eq!(l.clamp(1.0, 2.0), (1.0, false));
        assert_eq!(l.clamp(f64::NAN, 2.0), (0.0, true));
    }

    #[test]
    fn i2t_trips_after_about_tau_ln2_at_sqrt2_overload() {
        let mut l = lim(Some(1.0));
        let mut t = 0.0;
        while l.integrate_i2t(2f64.sqrt(), 1e-3).is_none() {
            t += 1e-3;
            assert!(t < 2.0);
        }
        assert!((t - 2f64.ln()).abs() < 0.01, "{t}");
        assert_eq!(lim(None).integrate_i2t(100.0, 1.0), None);
    }
}

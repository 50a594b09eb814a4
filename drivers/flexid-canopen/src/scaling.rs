//! SI conversions of the drive's process data, from a firmware profile's units.

use std::f64::consts::TAU;

/// Unit conversions of one drive, resolved at bring-up (values read from the drive
/// where the profile says "read").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scaling {
    /// Encoder increments per motor revolution (position unit: increments).
    pub increments_per_rev: f64,
    /// Rated torque (0x6076), N m: 1000 per-mille of target/actual torque.
    pub rated_torque_nm: f64,
    /// rad/s per unit of velocity actual value (0x606C).
    pub velocity_unit_rad_s: f64,
}

/// A torque set-point converted to per-mille of rated torque.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TorqueSetpoint {
    /// Per-mille of rated torque, as written to 0x6071.
    pub permille: i16,
    /// The requested torque did not fit an i16 (or was not finite) and was clamped
    /// (NaN gives 0).
    pub saturated: bool,
}

impl Scaling {
    /// Position actual (increments) to rad.
    pub fn position_rad(&self, increments: i64) -> f64 {
        increments as f64 * TAU / self.increments_per_rev
    }

    /// rad to increments (rounded, saturating at the i64 range).
    pub fn position_increments(&self, rad: f64) -> i64 {
        (rad * self.increments_per_rev / TAU).round() as i64
    }

    /// Velocity actual (drive units) to rad/s.
    pub fn velocity_rad_s(&self, raw: i32) -> f64 {
        raw as f64 * self.velocity_unit_rad_s
    }

    /// rad/s to drive velocity units (rounded, saturating at the i32 range).
    pub fn velocity_raw(&self, rad_s: f64) -> i32 {
        (rad_s / self.velocity_unit_rad_s).round() as i32
    }

    /// Torque (per-mille of rated torque) to N m.
    pub fn torque_nm(&self, permille: i16) -> f64 {
        permille as f64 * self.rated_torque_nm / 1000.0
    }

    /// N m to per-mille of rated torque, rounded, clamped to the i16 range (saturation
    /// reported).
    pub fn torque_permille(&self, nm: f64) -> TorqueSetpoint {
        let x = (nm * 1000.0 / self.rated_torque_nm).round();
        if x.is_nan() {
            return TorqueSetpoint {
                permille: 0,
                saturated: true,
            };
        }
        let clamped = x.clamp(i16::MIN as f64, i16::MAX as f64);
        TorqueSetpoint {
            permille: clamped as i16,
            saturated: clamped != x,
        }
    }
}

/// Extends the i32 position actual value to i64 across wrap-arounds (a multi-turn
/// position that overflows i32 keeps counting).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PositionUnwrap {
    last: Option<i32>,
    total: i64,
}

impl PositionUnwrap {
    /// Feeds the next raw position (increments); returns the unwrapped one.
    pub fn update(&mut self, raw: i32) -> i64 {
        match self.last {
            None => self.total = raw as i64,
            Some(last) => self.total += raw.wrapping_sub(last) as i64,
        }
        self.last = Some(raw);
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vdrive() -> Scaling {
        Scaling {
            increments_per_rev: (1u32 << 20) as f64,
            rated_torque_nm: 1.0,
            velocity_unit_rad_s: TAU / (1u32 << 20) as f64,
        }
    }

    #[test]
    fn round_trips() {
        let s = vdrive();
        assert!((s.position_rad(1 << 20) - TAU).abs() < 1e-12);
        assert!((s.position_rad(-(1 << 18)) + TAU / 4.0).abs() < 1e-12);
        for inc in [-123_456_789i64, -1, 0, 1, 1 << 20, 987_654_321] {
            assert_eq!(s.position_increments(s.position_rad(inc)), inc);
        }
        for v in [-5_000_000i32, -1, 0, 7, 1 << 20] {
            assert_eq!(s.velocity_raw(s.velocity_rad_s(v)), v);
        }
        assert!((s.velocity_rad_s(1 << 20) - TAU).abs() < 1e-12);
        for p in [-1000i16, -1, 0, 1, 250, 1000, i16::MAX] {
            let t = s.torque_permille(s.torque_nm(p));
            assert_eq!(
                t,
                TorqueSetpoint {
                    permille: p,
                    saturated: false
                }
            );
        }
        // rpm drive: 60 rpm = 2 pi rad/s
        let rpm = Scaling {
            velocity_unit_rad_s: TAU / 60.0,
            ..s
        };
        assert!((rpm.velocity_rad_s(60) - TAU).abs() < 1e-12);
    }

    #[test]
    fn torque_saturates_and_reports() {
        let s = Scaling {
            rated_torque_nm: 0.5,
            ..vdrive()
        };
        assert_eq!(
            s.torque_permille(0.25),
            TorqueSetpoint {
                permille: 500,
                saturated: false
            }
        );
        assert_eq!(
            s.torque_permille(100.0),
            TorqueSetpoint {
                permille: 32767,
                saturated: true
            }
        );
        assert_eq!(
            s.torque_permille(-100.0),
            TorqueSetpoint {
                permille: -32768,
                saturated: true
            }
        );
        assert_eq!(
            s.torque_permille(f64::NAN),
            TorqueSetpoint {
                permille: 0,
                saturated: true
            }
        );
        assert!(s.torque_permille(f64::INFINITY).saturated);
    }

    #[test]
    fn unwrap_counts_past_i32() {
        let mut u = PositionUnwrap::default();
        assert_eq!(u.update(i32::MAX - 10), (i32::MAX - 10) as i64);
        assert_eq!(u.update(i32::MIN + 9), i32::MAX as i64 + 10);
        assert_eq!(u.update(i32::MIN + 4), i32::MAX as i64 + 5);
    }
}

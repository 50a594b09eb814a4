//! A level's stepped-sine recording cut for the search's short simulations
//! ([`super::nlsim::shortened_stepped`]), made once per number of steady periods kept
//! instead of once per simulated candidate (the search simulates hundreds; each cut copied
//! every column of a record of 10⁵ samples and more).

use super::nlsim::shortened_stepped;
use crate::recording::Recording;
use std::borrow::Cow;
use std::sync::OnceLock;

/// Numbers of steady periods (1 to `KEPT`) whose cut is kept.
const KEPT: usize = 4;

/// The cut of one recording, and which recording it was cut from: the address and length
/// of its torque command (a level cloned with another recording misses the cache, and is
/// cut afresh).
type Cut = (usize, usize, Option<Recording>);

/// The kept cuts of one level's recording ([`super::Level::rec`]).
#[derive(Debug, Clone, Default)]
pub struct ShortenedCuts {
    cuts: [OnceLock<Cut>; KEPT],
}

impl ShortenedCuts {
    /// [`shortened_stepped`]`(rec, steady)`, from the kept cut when `rec` is the recording
    /// it was made from.
    pub fn get<'a>(&'a self, rec: &Recording, steady: usize) -> Option<Cow<'a, Recording>> {
        let key = (rec.torque_cmd_nm.as_ptr() as usize, rec.len());
        let Some(slot) = steady.checked_sub(1).and_then(|i| self.cuts.get(i)) else {
            return shortened_stepped(rec, steady).map(Cow::Owned);
        };
        let (ptr, len, cut) = slot.get_or_init(|| (key.0, key.1, shortened_stepped(rec, steady)));
        if (*ptr, *len) == key {
            cut.as_ref().map(Cow::Borrowed)
        } else {
            shortened_stepped(rec, steady).map(Cow::Owned)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::excitation::SteppedSineDesign;
    use crate::recording::Sidecar;

    fn stepped(scale: f64) -> Recording {
        let s = SteppedSineDesign {
            sample_rate_hz: 1000.0,
            frequencies_hz: vec![5.0, 50.0],
            min_period_samples: 100,
            periods: 4,
            settle_periods: 2,
            peak_limit_nm: 1.0,
            rms_limit_nm: 1.0,
        }
        .generate()
        .unwrap();
        let n = s.signal.len();
        Recording {
            time_s: (0..n).map(|k| k as f64 / 1000.0).collect(),
            torque_cmd_nm: s.signal.iter().map(|t| scale * t).collect(),
            position_rad: Some(vec![0.0; n]),
            velocity_rad_s: None,
            acceleration_rad_s2: None,
            torque_actual_nm: None,
            sample_rate_hz: 1000.0,
            sidecar: Sidecar {
                excitation: Some(s.info()),
                ..Sidecar::default()
            },
        }
    }

    /// The kept cut is the cut, borrowed from the second call on; another recording (a
    /// level cloned with a new one) is cut afresh; beyond the kept counts, cut each time.
    #[test]
    fn a_kept_cut_is_the_cut_of_its_own_recording() {
        let (a, b) = (stepped(1.0), stepped(2.0));
        let cuts = ShortenedCuts::default();
        for steady in [1, 2, 1, 7] {
            let want = shortened_stepped(&a, steady).map(|r| r.torque_cmd_nm);
            let got = cuts.get(&a, steady).map(|r| r.torque_cmd_nm.clone());
            assert_eq!(got, want, "{steady}");
        }
        assert!(matches!(cuts.get(&a, 1), Some(Cow::Borrowed(_))));
        let other = cuts.get(&b, 1).unwrap();
        assert!(matches!(other, Cow::Owned(_)));
        assert_eq!(
            other.torque_cmd_nm,
            shortened_stepped(&b, 1).unwrap().torque_cmd_nm
        );
    }

    /// A level's kept estimate is `estimate_frf` of its recording to the bit for the band
    /// it was made for; another band is estimated anew.
    #[test]
    fn a_levels_kept_estimate_is_the_estimate() {
        use crate::analysis::estimate_frf;
        use crate::diagnose::lti::LinExt;
        use crate::diagnose::nlsim::{simulate, Nl};
        use crate::diagnose::{prepare, DiagnoseOptions};
        let mut rec = stepped(1.0);
        let chain = crate::model::Chain::new(vec![1e-3, 2e-3], vec![400.0], vec![0.05]).unwrap();
        let mut lin = LinExt::nominal(chain);
        lin.motor_b = 0.05;
        rec.position_rad = Some(simulate(&lin, Nl::None, &rec.torque_cmd_nm, 1000.0, 2).pos);
        let data = prepare(
            std::slice::from_ref(&rec),
            &DiagnoseOptions {
                masses: 2,
                ..DiagnoseOptions::default()
            },
        )
        .unwrap();
        let bits = |e: &crate::analysis::EstimatedFrf| -> Vec<u64> {
            e.frf
                .h
                .iter()
                .flat_map(|h| [h.re.to_bits(), h.im.to_bits()])
                .chain(e.frf.var.iter().map(|v| v.to_bits()))
                .collect()
        };
        let level = &data.levels[0];
        for band in [None, Some([10.0, 100.0])] {
            let want = estimate_frf(&rec, band).unwrap();
            assert_eq!(
                bits(&level.measured(band).unwrap()),
                bits(&want),
                "{band:?}"
            );
        }
        assert!(level.measured.as_ref().is_some_and(|(b, _)| b.is_none()));
    }
}

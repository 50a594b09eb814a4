//! The ways the world's users excite an axis, each written with the sidecar description
//! flexid's recordings carry (`ExcitationInfo`): an odd random-phase multisine with
//! detection lines, Schroeder and random-phase multisines on the full grid (no detection
//! lines), a logarithmic swept sine, and a stepped sine; the same design at both levels.

use flexid::excitation::{
    AmplitudeShape, ChirpDesign, ExcitationInfo, MultisineDesign, PhaseDesign, SteppedSine,
    SteppedSineDesign,
};
use serde::{Deserialize, Serialize};

/// An excitation kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// Odd lines only, one in each group left out: detection lines for nonlinearity.
    OddRandom,
    /// Every line of the band, Schroeder phases.
    Schroeder,
    /// Every line of the band, random phases.
    RandomPhase,
    /// One logarithmic sweep over the band (estimated by Welch H1).
    SweptSine,
    /// Dwell blocks at log-spaced spot frequencies, played back to back.
    SteppedSine,
}

pub const KINDS: [Kind; 5] = [
    Kind::OddRandom,
    Kind::Schroeder,
    Kind::RandomPhase,
    Kind::SweptSine,
    Kind::SteppedSine,
];

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::OddRandom => "odd_random",
            Kind::Schroeder => "schroeder",
            Kind::RandomPhase => "random_phase",
            Kind::SweptSine => "swept_sine",
            Kind::SteppedSine => "stepped_sine",
        }
    }
}

/// One measurement's excitation design (the same at both levels but for the RMS).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Design {
    pub kind: Kind,
    pub fs_hz: f64,
    /// Line spacing of the periodic designs [Hz] (the sweep lasts as long as their record).
    pub line_spacing_hz: f64,
    pub band_hz: [f64; 2],
    /// Steady periods averaged, after `transient_periods`.
    pub periods: usize,
    pub transient_periods: usize,
    pub phase_seed: u64,
    /// Odd lines per group of the odd random-phase design (one left out per group).
    pub odd_group: usize,
    /// Spot frequencies of the stepped sine.
    pub stepped_spots: usize,
}

impl Design {
    pub fn period_samples(&self) -> usize {
        (self.fs_hz / self.line_spacing_hz).round() as usize
    }

    /// Seconds of a periodic record (transient periods included).
    pub fn periodic_duration_s(&self) -> f64 {
        ((self.periods + self.transient_periods) * self.period_samples()) as f64 / self.fs_hz
    }

    /// The full grid of lines in the band [Hz] (the visibility's reference multisine).
    pub fn grid_hz(&self) -> Vec<f64> {
        let df = self.line_spacing_hz;
        let lo = (self.band_hz[0] / df).ceil() as usize;
        let hi = (self.band_hz[1] / df).floor() as usize;
        (lo.max(1)..=hi).map(|k| k as f64 * df).collect()
    }

    /// The torque command [N m] at `rms_nm` and its description.
    pub fn generate(&self, rms_nm: f64) -> (Vec<f64>, ExcitationInfo) {
        let peak = 20.0 * rms_nm;
        let multisine = |phases: PhaseDesign, crest: usize| {
            let mut d = MultisineDesign::new(
                self.fs_hz,
                self.period_samples(),
                self.band_hz,
                peak,
                rms_nm,
            );
            d.phases = phases;
            d.amplitude = AmplitudeShape::Flat;
            d.crest_iterations = crest;
            let m = d.generate().expect("a valid multisine");
            (
                m.repeat(self.periods + self.transient_periods),
                m.info(self.periods, self.transient_periods),
            )
        };
        match self.kind {
            Kind::OddRandom => multisine(
                PhaseDesign::OddRandom {
                    seed: self.phase_seed,
                    group: self.odd_group,
                },
                10,
            ),
            Kind::Schroeder => multisine(PhaseDesign::Schroeder, 0),
            Kind::RandomPhase => multisine(
                PhaseDesign::Random {
                    seed: self.phase_seed,
                },
                10,
            ),
            Kind::SweptSine => {
                let dur = self.periodic_duration_s();
                let mut c =
                    ChirpDesign::new(self.fs_hz, self.band_hz[0], self.band_hz[1], dur, peak);
                c.taper_s = (0.05 * dur).min(0.5);
                c.rms_limit_nm = Some(rms_nm);
                let c = c.generate().expect("a valid sweep");
                let info = c.info();
                (c.signal, info)
            }
            Kind::SteppedSine => {
                let s = self.stepped(rms_nm);
                let info = s.info();
                (s.signal, info)
            }
        }
    }

    /// The stepped sine at `rms_nm`: `stepped_spots` log-spaced spots over the band.
    fn stepped(&self, rms_nm: f64) -> SteppedSine {
        let (lo, hi) = (self.band_hz[0], self.band_hz[1]);
        let n = self.stepped_spots.max(2);
        let spots = (0..n)
            .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
            .collect();
        let d = SteppedSineDesign {
            sample_rate_hz: self.fs_hz,
            frequencies_hz: spots,
            // 10 Hz resolution per block, at least 0.1 s per period
            min_period_samples: (0.1 * self.fs_hz).round() as usize,
            periods: 4,
            settle_periods: 3,
            peak_limit_nm: 20.0 * rms_nm,
            rms_limit_nm: rms_nm,
        };
        d.generate().expect("a valid stepped sine")
    }

    /// The energy `E` [N^2 m^2 x samples] of the excitation at `rms_nm` that an estimate of
    /// the response on each of `lines_hz` (spaced `line_spacing_hz`) averages: the scatter of
    /// `ln H` there is `sqrt(v / (|H|^2 E))` for a white noise `v` per sample on the reading.
    /// A periodic multisine with line amplitude `A` over `N` samples has `E = N A^2 / 4`; a
    /// logarithmic sweep spends a time `~ 1/f` per hertz, so its `E` falls as `1/f`: from
    /// the whole record's spectrum, `sum |U_j|^2 / N` over the bins within half a line
    /// spacing (the `H1` estimate over them). (A stepped sine's energy sits at its spots:
    /// [`super::visibility::Reference::line_energy`].)
    pub fn line_energy(&self, rms_nm: f64, lines_hz: &[f64]) -> Vec<f64> {
        let mut e = vec![0.0; lines_hz.len()];
        if lines_hz.is_empty() {
            return e;
        }
        let nearest = |f: f64| {
            let i = lines_hz.partition_point(|&l| l < f);
            [i.saturating_sub(1), i.min(lines_hz.len() - 1)]
                .into_iter()
                .min_by(|&a, &b| (lines_hz[a] - f).abs().total_cmp(&(lines_hz[b] - f).abs()))
        };
        let (u, _) = self.generate(rms_nm);
        let n = u.len();
        let mut planner = realfft::RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(n);
        let mut input = u;
        let mut spectrum = fft.make_output_vec();
        fft.process(&mut input, &mut spectrum)
            .expect("an FFT of the record's length");
        let half = 0.5 * self.line_spacing_hz;
        for (j, c) in spectrum.iter().enumerate().skip(1) {
            let f = j as f64 * self.fs_hz / n as f64;
            if let Some(l) = nearest(f).filter(|&l| (lines_hz[l] - f).abs() < half) {
                e[l] += c.norm_sqr() / n as f64;
            }
        }
        e
    }
}

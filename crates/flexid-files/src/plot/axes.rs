//! Axis coordinate types with explicit tick positions (plotters' own key-point wrapper has no
//! label formatter for `f64` ranges).

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use std::ops::Range;

/// A linear axis over `[lo, hi]` with the given tick values (grid and labels).
#[derive(Debug, Clone)]
pub(crate) struct LinearAxis {
    pub lo: f64,
    pub hi: f64,
    pub ticks: Vec<f64>,
}

/// A logarithmic axis over `[lo, hi]` (both > 0) with labelled major ticks and unlabelled
/// minor grid lines.
#[derive(Debug, Clone)]
pub(crate) struct LogAxis {
    pub lo: f64,
    pub hi: f64,
    pub major: Vec<f64>,
    pub minor: Vec<f64>,
}

fn to_pixel(t: f64, limit: (i32, i32)) -> i32 {
    let px = limit.0 as f64 + t * (limit.1 - limit.0) as f64;
    px.clamp(-1e6, 1e6).round() as i32
}

impl Ranged for LinearAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        to_pixel((v - self.lo) / (self.hi - self.lo), limit)
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

impl Ranged for LogAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let (a, b) = (self.lo.ln(), self.hi.ln());
        to_pixel((v.max(f64::MIN_POSITIVE).ln() - a) / (b - a), limit)
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.major.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

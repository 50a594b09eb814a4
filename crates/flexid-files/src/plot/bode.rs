//! The Bode plot builder and its SVG rendering.

use super::axes::{LinearAxis, LogAxis};
use super::error::PlotError;
use super::series::{
    interp_log, log_ticks, measured_curves, model_curves, nice_ticks, runs, Curves, DB_STEPS,
    DEG_STEPS,
};
use super::units::magnitude_label;
use flexid_core::frf::Frf;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

const FONT: &str = "sans-serif";
const MEASURED: RGBColor = RGBColor(31, 78, 153);
const BAND_OPACITY: f64 = 0.22;
const MODEL_COLOURS: [RGBColor; 4] = [
    RGBColor(226, 94, 0),
    RGBColor(0, 140, 70),
    RGBColor(170, 40, 150),
    RGBColor(120, 110, 0),
];
const AR_COLOUR: RGBColor = RGBColor(110, 50, 160);
const R_COLOUR: RGBColor = RGBColor(30, 30, 30);
const GRID_MAJOR: RGBColor = RGBColor(195, 195, 195);
const GRID_MINOR: RGBColor = RGBColor(232, 232, 232);
const TEXT: RGBColor = RGBColor(25, 25, 25);
const SUBTLE: RGBColor = RGBColor(90, 90, 90);
/// Width of the y label area [px]; the same for all panels so their x axes align.
const Y_LABEL_AREA: u32 = 88;
const MARGIN_LEFT: u32 = 12;
const MARGIN_RIGHT: u32 = 28;

/// A Bode plot of a measured frequency response with optional model curves and
/// resonance / anti-resonance markers, rendered as SVG.
///
/// Panels share a logarithmic frequency axis [Hz]: magnitude [dB] with the measured curve
/// and its shaded ±2σ band (σ = sqrt(var); the band on |H| is |H| ± 2σ, its lower edge
/// clamped at most 40 dB below the curve), phase [deg] (unwrapped, band ± 2σ/|H| rad), and
/// coherence [-] when the measured response has one. Model curves are drawn on top in
/// contrasting colours; anti-resonances get a dashed vertical line and a downward marker,
/// resonances a solid line and an upward marker, each labelled like `AR1 52.9 Hz` /
/// `R1 77.1 Hz` (numbered by increasing frequency). Lines with `var = +inf` are gaps.
///
/// ```no_run
/// # fn f(measured: &flexid_core::frf::Frf, model: &flexid_core::frf::Frf) -> Result<(), flexid_files::plot::PlotError> {
/// use flexid_files::plot::BodePlot;
/// BodePlot::new(measured)
///     .model(model, "identified 3-mass model")
///     .anti_resonances(&[52.9])
///     .resonances(&[77.1])
///     .title("Axis 2")
///     .write_svg("axis2_bode.svg")?;
/// # Ok(()) }
/// ```
#[derive(Debug, Clone)]
pub struct BodePlot<'a> {
    measured: &'a Frf,
    models: Vec<(&'a Frf, String)>,
    anti_resonances_hz: Vec<f64>,
    resonances_hz: Vec<f64>,
    title: Option<String>,
    subtitle: Option<String>,
    size_px: (u32, u32),
    sigmas: f64,
    band_used_hz: Option<[f64; 2]>,
}

/// One marker ready to draw.
struct Marker {
    freq_hz: f64,
    label: String,
    anti: bool,
}

impl<'a> BodePlot<'a> {
    /// Default picture size [px].
    pub const DEFAULT_SIZE_PX: (u32, u32) = (1000, 800);

    /// A plot of `measured` at the default size, 1000 x 800 px.
    pub fn new(measured: &'a Frf) -> Self {
        Self {
            measured,
            models: Vec::new(),
            anti_resonances_hz: Vec::new(),
            resonances_hz: Vec::new(),
            title: None,
            subtitle: None,
            size_px: Self::DEFAULT_SIZE_PX,
            sigmas: 2.0,
            band_used_hz: None,
        }
    }

    /// The band [Hz] the identification used: the lines outside it (which carry no
    /// information: their uncertainty exceeds the response) are shaded grey.
    pub fn band_used(mut self, band_hz: [f64; 2]) -> Self {
        self.band_used_hz = Some(band_hz);
        self
    }

    /// Add a model curve with its legend label, e.g. "identified 3-mass model". Its `var` and
    /// `coherence` are ignored; lines outside the measured frequency range are not drawn.
    pub fn model(mut self, frf: &'a Frf, label: impl Into<String>) -> Self {
        self.models.push((frf, label.into()));
        self
    }

    /// Mark an anti-resonance at `freq_hz` [Hz].
    pub fn anti_resonance(mut self, freq_hz: f64) -> Self {
        self.anti_resonances_hz.push(freq_hz);
        self
    }

    /// Mark anti-resonances at these frequencies [Hz].
    pub fn anti_resonances(mut self, freq_hz: &[f64]) -> Self {
        self.anti_resonances_hz.extend_from_slice(freq_hz);
        self
    }

    /// Mark a resonance at `freq_hz` [Hz].
    pub fn resonance(mut self, freq_hz: f64) -> Self {
        self.resonances_hz.push(freq_hz);
        self
    }

    /// Mark resonances at these frequencies [Hz].
    pub fn resonances(mut self, freq_hz: &[f64]) -> Self {
        self.resonances_hz.extend_from_slice(freq_hz);
        self
    }

    /// Title line above the panels.
    pub fn title(mut self, title: impl Into<String>) -> Self {
        self.title = Some(title.into());
        self
    }

    /// Second, smaller line below the title (e.g. recording name and date).
    pub fn subtitle(mut self, subtitle: impl Into<String>) -> Self {
        self.subtitle = Some(subtitle.into());
        self
    }

    /// Picture size [px] (at least 400 x 300).
    pub fn size(mut self, width_px: u32, height_px: u32) -> Self {
        self.size_px = (width_px, height_px);
        self
    }

    /// Render and write the SVG to `path`, replacing the file atomically
    /// (see [`crate::recording::write_atomic`]).
    pub fn write_svg(&self, path: impl AsRef<Path>) -> Result<(), PlotError> {
        let svg = self.render_svg()?;
        let path = path.as_ref();
        crate::recording::write_bytes_atomic(path, svg.as_bytes()).map_err(|source| PlotError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    fn markers(&self, lo: f64, hi: f64) -> Result<Vec<Marker>, PlotError> {
        let mut out = Vec::new();
        for (list, prefix, anti) in [
            (&self.anti_resonances_hz, "AR", true),
            (&self.resonances_hz, "R", false),
        ] {
            let mut f: Vec<f64> = list.clone();
            if let Some(&bad) = f.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                return Err(PlotError::InvalidMarker { freq_hz: bad });
            }
            f.sort_by(f64::total_cmp);
            for (i, &v) in f.iter().enumerate() {
                if v >= lo && v <= hi {
                    out.push(Marker {
                        freq_hz: v,
                        label: format!("{prefix}{} {}", i + 1, super::series::marker_freq_text(v)),
                        anti,
                    });
                }
            }
        }
        Ok(out)
    }

    /// Render the plot as an SVG document.
    ///
    /// Errors: [`PlotError::Empty`] (no lines, or no line with finite variance),
    /// [`PlotError::LengthMismatch`], [`PlotError::InvalidFrequency`],
    /// [`PlotError::InvalidResponse`], [`PlotError::InvalidVariance`] (zero, negative or NaN
    /// variance of the measured response), [`PlotError::InvalidCoherence`],
    /// [`PlotError::InvalidMarker`], [`PlotError::InvalidSize`].
    pub fn render_svg(&self) -> Result<String, PlotError> {
        let (w, h) = self.size_px;
        if w < 400 || h < 300 {
            return Err(PlotError::InvalidSize {
                width_px: w,
                height_px: h,
            });
        }
        let mut meas = measured_curves(self.measured, self.sigmas)?;
        if let Some(band) = self.band_used_hz {
            // unwrapping through lines without information runs away (thousands of
            // degrees): unwrap inside the band only, wrap the rest around its edges
            let wrapped: Vec<f64> = self
                .measured
                .h
                .iter()
                .map(|h| h.arg().to_degrees())
                .collect();
            meas.phase_deg = phase_unwrapped_in_band(&self.measured.freq_hz, &wrapped, band);
        }
        let models = self
            .models
            .iter()
            .map(|(frf, label)| Ok((model_curves(frf, label, &meas)?, label.as_str())))
            .collect::<Result<Vec<_>, PlotError>>()?;
        let mut lo = meas.freq_hz[0];
        let mut hi = meas.freq_hz[meas.freq_hz.len() - 1];
        if hi / lo < 1.01 {
            lo /= 1.5;
            hi *= 1.5;
        }
        let markers = self.markers(lo, hi)?;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
            root.fill(&WHITE).map_err(render)?;
            let ctx = Ctx {
                meas: &meas,
                models: &models,
                markers: &markers,
                lo,
                hi,
                kind_label: magnitude_label(self.measured.kind),
                band_used: self.band_used_hz,
            };
            self.draw(&root, &ctx)?;
            root.present().map_err(render)?;
        }
        Ok(svg)
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
        ctx: &Ctx,
    ) -> Result<(), PlotError> {
        let (w, h) = self.size_px;
        let mut header_h = 14;
        if self.title.is_some() {
            header_h += 28;
        }
        if self.subtitle.is_some() {
            header_h += 22;
        }
        let legend_y = header_h as i32 + 6;
        header_h += 30;
        let (header, body) = root.split_vertically(header_h);
        self.draw_header(&header, ctx, legend_y)?;

        let has_coh = ctx.meas.coherence.is_some();
        let x_axis_h = 58u32;
        let avail = h.saturating_sub(header_h + x_axis_h) as f64;
        let fr: &[f64] = if has_coh {
            &[0.47, 0.32, 0.21]
        } else {
            &[0.58, 0.42]
        };
        let mut heights: Vec<u32> = fr.iter().map(|f| (f * avail) as u32).collect();
        *heights.last_mut().expect("panels") += x_axis_h;
        let mut rest = body;
        let mut areas = Vec::new();
        for (i, &ph) in heights.iter().enumerate() {
            if i + 1 == heights.len() {
                areas.push(rest.clone());
            } else {
                let (a, b) = rest.split_vertically(ph);
                areas.push(a);
                rest = b;
            }
        }
        let _ = w;
        let n = areas.len();
        self.draw_magnitude(root, &areas[0], ctx, n == 1)?;
        self.draw_phase(&areas[1], ctx, n == 2)?;
        if has_coh {
            self.draw_coherence(&areas[2], ctx)?;
        }
        Ok(())
    }

    fn draw_header<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, plotters::coord::Shift>,
        ctx: &Ctx,
        legend_y: i32,
    ) -> Result<(), PlotError> {
        let x0 = (MARGIN_LEFT + Y_LABEL_AREA) as i32;
        let mut y = 12;
        if let Some(t) = &self.title {
            let style = (FONT, 21).into_font().style(FontStyle::Bold).color(&TEXT);
            area.draw(&Text::new(t.clone(), (x0, y), style))
                .map_err(render)?;
            y += 28;
        }
        if let Some(s) = &self.subtitle {
            let style = (FONT, 15).into_font().color(&SUBTLE);
            area.draw(&Text::new(s.clone(), (x0, y), style))
                .map_err(render)?;
        }
        // Legend row.
        let font = (FONT, 14).into_font().color(&TEXT);
        let text_style = font.pos(Pos::new(HPos::Left, VPos::Center));
        let cy = legend_y + 8;
        let mut x = x0;
        let item = |x: &mut i32, label: &str, glyph: Glyph| -> Result<(), PlotError> {
            let gx = *x;
            match glyph {
                Glyph::Line(c, dashed) => {
                    if dashed {
                        for k in 0..4 {
                            let a = gx + k * 8;
                            area.draw(&PathElement::new(
                                vec![(a, cy), (a + 5, cy)],
                                c.stroke_width(2),
                            ))
                            .map_err(render)?;
                        }
                    } else {
                        area.draw(&PathElement::new(
                            vec![(gx, cy), (gx + 28, cy)],
                            c.stroke_width(if c == MEASURED { 2 } else { 3 }),
                        ))
                        .map_err(render)?;
                    }
                }
                Glyph::Band => {
                    area.draw(&Rectangle::new(
                        [(gx, cy - 6), (gx + 28, cy + 6)],
                        MEASURED.mix(BAND_OPACITY).filled(),
                    ))
                    .map_err(render)?;
                }
                Glyph::Unused => {
                    area.draw(&Rectangle::new(
                        [(gx, cy - 6), (gx + 28, cy + 6)],
                        UNUSED.mix(UNUSED_OPACITY).filled(),
                    ))
                    .map_err(render)?;
                }
                Glyph::Triangle(c, up) => {
                    area.draw(&PathElement::new(
                        vec![(gx + 14, cy - 9), (gx + 14, cy + 9)],
                        c.stroke_width(1),
                    ))
                    .map_err(render)?;
                    area.draw(&triangle((gx + 14, cy), up, c)).map_err(render)?;
                }
            }
            area.draw(&Text::new(
                label.to_string(),
                (gx + 34, cy),
                text_style.clone(),
            ))
            .map_err(render)?;
            *x = gx + 34 + text_width(label, 14) + 26;
            Ok(())
        };
        item(&mut x, "measured", Glyph::Line(MEASURED, false))?;
        item(&mut x, "±2σ uncertainty", Glyph::Band)?;
        if ctx.band_used.is_some() {
            item(&mut x, "no information (SNR < 2), not used", Glyph::Unused)?;
        }
        for (i, (_, label)) in ctx.models.iter().enumerate() {
            item(&mut x, label, Glyph::Line(model_colour(i), false))?;
        }
        if ctx.markers.iter().any(|m| m.anti) {
            item(&mut x, "anti-resonance", Glyph::Triangle(AR_COLOUR, false))?;
        }
        if ctx.markers.iter().any(|m| !m.anti) {
            item(&mut x, "resonance", Glyph::Triangle(R_COLOUR, true))?;
        }
        Ok(())
    }

    fn draw_magnitude<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
        area: &DrawingArea<DB, plotters::coord::Shift>,
        ctx: &Ctx,
        bottom: bool,
    ) -> Result<(), PlotError> {
        let meas = ctx.meas;
        let mut vals: Vec<f64> = (0..meas.freq_hz.len())
            .filter(|&i| meas.usable[i])
            .map(|i| meas.mag_db[i])
            .collect();
        for (m, _) in ctx.models {
            vals.extend(in_range(m, ctx, |m, i| m.mag_db[i]));
        }
        let (dmin, dmax) = min_max(&vals);
        let span = (dmax - dmin).max(6.0);
        let top_pad = if ctx.markers.iter().any(|m| !m.anti) {
            0.16
        } else {
            0.06
        };
        let bot_pad = if ctx.markers.iter().any(|m| m.anti) {
            0.16
        } else {
            0.06
        };
        let (ylo, yhi, ticks) =
            nice_ticks(dmin - bot_pad * span, dmax + top_pad * span, 9, &DB_STEPS);
        let mut chart = panel(area, ctx, ylo, yhi, ticks, &ctx.kind_label, bottom)?;
        // Band: one polygon per run of usable lines.
        let band = MEASURED.mix(BAND_OPACITY).filled();
        let clamp = |v: f64| v.clamp(ylo, yhi);
        for r in runs(&meas.usable) {
            let up = r
                .clone()
                .map(|i| (meas.freq_hz[i], clamp(meas.mag_band[i].expect("usable").1)));
            let down = r
                .clone()
                .rev()
                .map(|i| (meas.freq_hz[i], clamp(meas.mag_band[i].expect("usable").0)));
            let pts: Vec<(f64, f64)> = up.chain(down).collect();
            if r.len() > 1 {
                chart
                    .draw_series(std::iter::once(Polygon::new(pts, band)))
                    .map_err(render)?;
            } else {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        pts,
                        MEASURED.mix(0.35).stroke_width(4),
                    )))
                    .map_err(render)?;
            }
        }
        self.draw_marker_lines(&mut chart, ctx, ylo, yhi)?;
        draw_curves(&mut chart, ctx, |c, i| c.mag_db[i], ylo, yhi)?;
        // Markers on the measured curve, labels in rows at the top (R) and bottom (AR).
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        let mut rows_top: Vec<i32> = Vec::new();
        let mut rows_bot: Vec<i32> = Vec::new();
        let usable_f: Vec<f64> = (0..meas.freq_hz.len())
            .filter(|&i| meas.usable[i])
            .map(|i| meas.freq_hz[i])
            .collect();
        let usable_db: Vec<f64> = (0..meas.freq_hz.len())
            .filter(|&i| meas.usable[i])
            .map(|i| meas.mag_db[i])
            .collect();
        let label_font = 13;
        for m in ctx.markers {
            let db = clamp(interp_log(&usable_f, &usable_db, m.freq_hz));
            let (px, py) = chart.backend_coord(&(m.freq_hz, db));
            let colour = if m.anti { AR_COLOUR } else { R_COLOUR };
            // Marker: downward triangle for an AR, upward for an R.
            // Outside the extremum: below a dip, above a peak.
            let tip = if m.anti { (px, py + 16) } else { (px, py - 16) };
            root.draw(&triangle_tip(tip, !m.anti, colour))
                .map_err(render)?;
            let tw = text_width(&m.label, label_font);
            let left_anchored = px + 5 + tw < xr.end - 2;
            let (lx, anchor) = if left_anchored {
                (px + 5, HPos::Left)
            } else {
                (px - 5, HPos::Right)
            };
            let (l, r) = if left_anchored {
                (lx, lx + tw)
            } else {
                (lx - tw, lx)
            };
            let rows = if m.anti { &mut rows_bot } else { &mut rows_top };
            let row = match rows.iter().position(|&end| l > end + 6) {
                Some(k) => k,
                None => {
                    rows.push(i32::MIN);
                    rows.len() - 1
                }
            };
            rows[row] = r;
            let ly = if m.anti {
                yr.end - 12 - row as i32 * 18
            } else {
                yr.start + 12 + row as i32 * 18
            };
            root.draw(&Rectangle::new(
                [(l - 3, ly - 9), (r + 3, ly + 9)],
                WHITE.mix(0.85).filled(),
            ))
            .map_err(render)?;
            let style = (FONT, label_font)
                .into_font()
                .color(&colour)
                .pos(Pos::new(anchor, VPos::Center));
            root.draw(&Text::new(m.label.clone(), (lx, ly), style))
                .map_err(render)?;
        }
        Ok(())
    }

    fn draw_phase<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, plotters::coord::Shift>,
        ctx: &Ctx,
        bottom: bool,
    ) -> Result<(), PlotError> {
        let meas = ctx.meas;
        let mut vals: Vec<f64> = (0..meas.freq_hz.len())
            .filter(|&i| meas.usable[i])
            .map(|i| meas.phase_deg[i])
            .collect();
        for (m, _) in ctx.models {
            vals.extend(in_range(m, ctx, |m, i| m.phase_deg[i]));
        }
        let (pmin, pmax) = min_max(&vals);
        let span = (pmax - pmin).max(30.0);
        let (ylo, yhi, ticks) = nice_ticks(pmin - 0.08 * span, pmax + 0.08 * span, 8, &DEG_STEPS);
        let mut chart = panel(area, ctx, ylo, yhi, ticks, "Phase [deg]", bottom)?;
        let band = MEASURED.mix(BAND_OPACITY).filled();
        let clamp = |v: f64| v.clamp(ylo, yhi);
        for r in runs(&meas.usable) {
            let half = |i: usize| meas.phase_band[i].expect("usable");
            let up = r
                .clone()
                .map(|i| (meas.freq_hz[i], clamp(meas.phase_deg[i] + half(i))));
            let down = r
                .clone()
                .rev()
                .map(|i| (meas.freq_hz[i], clamp(meas.phase_deg[i] - half(i))));
            let pts: Vec<(f64, f64)> = up.chain(down).collect();
            if r.len() > 1 {
                chart
                    .draw_series(std::iter::once(Polygon::new(pts, band)))
                    .map_err(render)?;
            } else {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        pts,
                        MEASURED.mix(0.35).stroke_width(4),
                    )))
                    .map_err(render)?;
            }
        }
        self.draw_marker_lines(&mut chart, ctx, ylo, yhi)?;
        draw_curves(&mut chart, ctx, |c, i| c.phase_deg[i], ylo, yhi)?;
        Ok(())
    }

    fn draw_coherence<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, plotters::coord::Shift>,
        ctx: &Ctx,
    ) -> Result<(), PlotError> {
        let meas = ctx.meas;
        let coh = meas.coherence.as_ref().expect("checked");
        let ticks = vec![0.0, 0.25, 0.5, 0.75, 1.0];
        let mut chart = panel(area, ctx, 0.0, 1.05, ticks, "Coherence [-]", true)?;
        self.draw_marker_lines(&mut chart, ctx, 0.0, 1.05)?;
        for r in runs(&meas.usable) {
            let pts: Vec<(f64, f64)> = r.map(|i| (meas.freq_hz[i], coh[i])).collect();
            chart
                .draw_series(std::iter::once(PathElement::new(
                    pts,
                    MEASURED.stroke_width(2),
                )))
                .map_err(render)?;
        }
        Ok(())
    }

    fn draw_marker_lines<DB: DrawingBackend>(
        &self,
        chart: &mut Chart<'_, DB>,
        ctx: &Ctx,
        ylo: f64,
        yhi: f64,
    ) -> Result<(), PlotError> {
        for m in ctx.markers {
            let pts = vec![(m.freq_hz, ylo), (m.freq_hz, yhi)];
            if m.anti {
                chart
                    .draw_series(DashedLineSeries::new(
                        pts,
                        6,
                        4,
                        AR_COLOUR.mix(0.8).stroke_width(1),
                    ))
                    .map_err(render)?;
            } else {
                chart
                    .draw_series(LineSeries::new(pts, R_COLOUR.mix(0.6).stroke_width(1)))
                    .map_err(render)?;
            }
        }
        Ok(())
    }
}

/// Shared data of one rendering.
struct Ctx<'c> {
    meas: &'c Curves,
    models: &'c [(Curves, &'c str)],
    markers: &'c [Marker],
    lo: f64,
    hi: f64,
    kind_label: String,
    band_used: Option<[f64; 2]>,
}

enum Glyph {
    Line(RGBColor, bool),
    Band,
    Unused,
    Triangle(RGBColor, bool),
}

/// The shade over lines outside the band used.
const UNUSED: RGBColor = RGBColor(150, 150, 150);
const UNUSED_OPACITY: f64 = 0.22;

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<LogAxis, LinearAxis>>;

fn render<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Render(e.to_string())
}

fn model_colour(i: usize) -> RGBColor {
    MODEL_COLOURS[i % MODEL_COLOURS.len()]
}

/// Estimated width of `s` in a sans-serif font of `size` px.
fn text_width(s: &str, size: u32) -> i32 {
    (s.chars().count() as f64 * size as f64 * 0.53).ceil() as i32
}

fn min_max(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        })
}

fn in_range<'c>(c: &'c Curves, ctx: &Ctx, f: impl Fn(&Curves, usize) -> f64 + 'c) -> Vec<f64> {
    (0..c.freq_hz.len())
        .filter(|&i| c.freq_hz[i] >= ctx.lo && c.freq_hz[i] <= ctx.hi)
        .map(|i| f(c, i))
        .collect()
}

/// A filled triangle centred at `c` (pixels), pointing up or down.
fn triangle(c: (i32, i32), up: bool, colour: RGBColor) -> Polygon<(i32, i32)> {
    let (x, y) = c;
    let pts = if up {
        vec![(x - 6, y + 5), (x + 6, y + 5), (x, y - 6)]
    } else {
        vec![(x - 6, y - 5), (x + 6, y - 5), (x, y + 6)]
    };
    Polygon::new(pts, colour.filled())
}

/// A filled triangle 12 px high with its tip at `tip` (pixels), pointing up or down.
fn triangle_tip(tip: (i32, i32), up: bool, colour: RGBColor) -> Polygon<(i32, i32)> {
    let (x, y) = tip;
    let pts = if up {
        vec![(x - 6, y + 11), (x + 6, y + 11), (x, y)]
    } else {
        vec![(x - 6, y - 11), (x + 6, y - 11), (x, y)]
    };
    Polygon::new(pts, colour.filled())
}

/// One panel: log frequency axis, grid at decades, y ticks as given.
fn panel<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    ctx: &Ctx,
    ylo: f64,
    yhi: f64,
    yticks: Vec<f64>,
    ylabel: &str,
    bottom: bool,
) -> Result<Chart<'a, DB>, PlotError> {
    let first = ylabel.starts_with("Magnitude");
    let (major, minor) = log_ticks(ctx.lo, ctx.hi);
    let mut chart = ChartBuilder::on(area)
        .margin_left(MARGIN_LEFT)
        .margin_right(MARGIN_RIGHT)
        .margin_top(if first { 8 } else { 16 })
        .margin_bottom(if bottom { 8 } else { 10 })
        .y_label_area_size(Y_LABEL_AREA)
        .x_label_area_size(if bottom { 50 } else { 0 })
        .build_cartesian_2d(
            LogAxis {
                lo: ctx.lo,
                hi: ctx.hi,
                major,
                minor,
            },
            LinearAxis {
                lo: ylo,
                hi: yhi,
                ticks: yticks,
            },
        )
        .map_err(render)?;
    let step = (yhi - ylo).abs();
    let yfmt = move |v: &f64| {
        if step <= 3.0 {
            let s = format!("{v:.2}");
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            format!("{v:.0}")
        }
    };
    let xfmt = |v: &f64| super::series::freq_label(*v);
    chart
        .configure_mesh()
        .bold_line_style(GRID_MAJOR.stroke_width(1))
        .light_line_style(GRID_MINOR.stroke_width(1))
        .axis_style(SUBTLE.stroke_width(1))
        .x_label_formatter(&xfmt)
        .y_label_formatter(&yfmt)
        .x_desc(if bottom { "Frequency [Hz]" } else { "" })
        .y_desc(ylabel)
        .label_style((FONT, 14).into_font().color(&TEXT))
        .axis_desc_style((FONT, 15).into_font().color(&TEXT))
        .draw()
        .map_err(render)?;
    if let Some([a, b]) = ctx.band_used {
        let shade = UNUSED.mix(UNUSED_OPACITY).filled();
        for (x0, x1) in [(ctx.lo, a.max(ctx.lo)), (b.min(ctx.hi), ctx.hi)] {
            if x1 > x0 {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x0, ylo), (x1, yhi)],
                        shade,
                    )))
                    .map_err(render)?;
            }
        }
    }
    Ok(chart)
}

/// Measured curve (runs of usable lines), then the model curves on top.
fn draw_curves<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    ctx: &Ctx,
    y: impl Fn(&Curves, usize) -> f64,
    ylo: f64,
    yhi: f64,
) -> Result<(), PlotError> {
    let meas = ctx.meas;
    for r in runs(&meas.usable) {
        if r.len() == 1 {
            let i = r.start;
            chart
                .draw_series(std::iter::once(Circle::new(
                    (meas.freq_hz[i], y(meas, i).clamp(ylo, yhi)),
                    2,
                    MEASURED.filled(),
                )))
                .map_err(render)?;
        } else {
            let pts: Vec<(f64, f64)> = r
                .map(|i| (meas.freq_hz[i], y(meas, i).clamp(ylo, yhi)))
                .collect();
            chart
                .draw_series(LineSeries::new(pts, MEASURED.stroke_width(2)))
                .map_err(render)?;
        }
    }
    for (k, (m, _)) in ctx.models.iter().enumerate() {
        let pts: Vec<(f64, f64)> = (0..m.freq_hz.len())
            .filter(|&i| m.freq_hz[i] >= ctx.lo && m.freq_hz[i] <= ctx.hi)
            .map(|i| (m.freq_hz[i], y(m, i).clamp(ylo, yhi)))
            .collect();
        chart
            .draw_series(LineSeries::new(pts, model_colour(k).stroke_width(1)))
            .map_err(render)?;
    }
    Ok(())
}

/// The phase [deg] unwrapped along frequency over the lines inside `band` [Hz] only (from
/// the wrapped phase `wrapped_deg`); below the band every line is wrapped to within 180
/// degrees of the band's first line, above it to within 180 degrees of its last. Without
/// a line in the band, the wrapped phase.
fn phase_unwrapped_in_band(freq_hz: &[f64], wrapped_deg: &[f64], band: [f64; 2]) -> Vec<f64> {
    let inside = |f: f64| f >= band[0] && f <= band[1];
    let (Some(i0), Some(i1)) = (
        freq_hz.iter().position(|f| inside(*f)),
        freq_hz.iter().rposition(|f| inside(*f)),
    ) else {
        return wrapped_deg.to_vec();
    };
    let near = |p: f64, reference: f64| p - ((p - reference) / 360.0).round() * 360.0;
    let mut out = wrapped_deg.to_vec();
    for i in i0 + 1..=i1 {
        out[i] = near(wrapped_deg[i], out[i - 1]);
    }
    for i in 0..i0 {
        out[i] = near(wrapped_deg[i], out[i0]);
    }
    for i in i1 + 1..out.len() {
        out[i] = near(wrapped_deg[i], out[i1]);
    }
    out
}

#[cfg(test)]
mod phase_tests {
    use super::phase_unwrapped_in_band;

    #[test]
    fn the_phase_is_unwrapped_inside_the_band_and_bounded_outside() {
        // a phase falling 30 degrees per line (wrapped), the band over lines 2..=6
        let f: Vec<f64> = (0..12).map(|k| 1.0 + k as f64).collect();
        let true_deg: Vec<f64> = (0..12).map(|k| -30.0 * k as f64).collect();
        let wrapped: Vec<f64> = true_deg
            .iter()
            .map(|p| p - ((p + 180.0) / 360.0).floor() * 360.0)
            .collect();
        let out = phase_unwrapped_in_band(&f, &wrapped, [3.0, 7.0]);
        for k in 2..=6 {
            assert!(
                (out[k] - (true_deg[k] - true_deg[2] + out[2])).abs() < 1e-9,
                "{k}: {out:?}"
            );
        }
        for k in (0..2).chain(7..12) {
            let edge = if k < 2 { out[2] } else { out[6] };
            assert!((out[k] - edge).abs() <= 180.0, "{k}: {out:?}");
        }
        // no line in the band: the wrapped phase
        assert_eq!(
            phase_unwrapped_in_band(&f, &wrapped, [100.0, 200.0]),
            wrapped
        );
    }
}

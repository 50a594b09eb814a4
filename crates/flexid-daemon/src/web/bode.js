// The Bode plot of the daemon page: magnitude [dB], phase [deg] and coherence [-] over a
// logarithmic frequency axis [Hz], drawn as SVG. No dependencies.
'use strict';

const SVG_NS = 'http://www.w3.org/2000/svg';
// Values the daemon sends for non-finite numbers (f64::MAX) are gaps.
const GAP = 1e300;

/** Layout of the three panels inside the 960 x 620 view box. */
const PLOT = {
  left: 78, right: 940,
  panels: [
    { key: 'mag', top: 16, bottom: 246, label: '|H| [dB re 1 (rad/s)/(N m)]' },
    { key: 'phase', top: 276, bottom: 446, label: 'phase [deg]' },
    { key: 'coh', top: 476, bottom: 576, label: 'coherence [-]' },
  ],
  xLabel: 'frequency [Hz]',
};

function el(name, attrs, parent) {
  const e = document.createElementNS(SVG_NS, name);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, String(v));
  if (parent) parent.appendChild(e);
  return e;
}

function text(parent, x, y, s, attrs) {
  const t = el('text', Object.assign({ x, y }, attrs || {}), parent);
  t.textContent = s;
  return t;
}

/** Linear ticks at a "nice" step (1, 2, 5 x 10^k) covering [lo, hi]. */
function niceStep(lo, hi, count) {
  const raw = (hi - lo) / Math.max(1, count);
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

function linTicks(lo, hi, step) {
  const out = [];
  for (let v = Math.ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) out.push(+v.toFixed(9));
  return out;
}

/** Range of the finite values of several arrays, padded to whole steps. */
function range(arrays, step, minSpan) {
  let lo = Infinity, hi = -Infinity;
  for (const a of arrays) for (const v of a || []) {
    if (Number.isFinite(v) && Math.abs(v) < GAP) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  }
  if (!Number.isFinite(lo)) return [-step, step];
  if (hi - lo < minSpan) { const c = (hi + lo) / 2; lo = c - minSpan / 2; hi = c + minSpan / 2; }
  return [Math.floor(lo / step) * step, Math.ceil(hi / step) * step];
}

function fmtHz(f) {
  return f >= 1000 ? (f / 1000) + 'k' : String(+f.toPrecision(3));
}

/** Path through (x, y) points; a gap (non-finite y) breaks the line. */
function pathD(xs, ys, sx, sy) {
  let d = '', pen = false;
  for (let i = 0; i < xs.length; i++) {
    const y = ys[i];
    if (!(Number.isFinite(y) && Math.abs(y) < GAP) || !(xs[i] > 0)) { pen = false; continue; }
    d += (pen ? 'L' : 'M') + sx(xs[i]).toFixed(1) + ' ' + sy(y).toFixed(1);
    pen = true;
  }
  return d;
}

/** Closed band between lower and upper curves. */
function bandD(xs, lo, hi, sx, sy) {
  const ok = (i) => xs[i] > 0 && Number.isFinite(lo[i]) && Number.isFinite(hi[i]) &&
    Math.abs(lo[i]) < GAP && Math.abs(hi[i]) < GAP;
  const idx = xs.map((_, i) => i).filter(ok);
  if (idx.length < 2) return '';
  let d = 'M' + idx.map((i) => sx(xs[i]).toFixed(1) + ' ' + sy(hi[i]).toFixed(1)).join('L');
  d += 'L' + idx.reverse().map((i) => sx(xs[i]).toFixed(1) + ' ' + sy(lo[i]).toFixed(1)).join('L');
  return d + 'Z';
}

/**
 * Draw the plot into `svg`.
 * data = { estimates: [bode events, oldest first], model: {freq_hz, magnitude_db, phase_deg} | null }
 * A bode event: {period, freq_hz[], magnitude_db[], phase_deg[], coherence[] | null, relative_std[]}.
 */
function drawBode(svg, data) {
  while (svg.firstChild) svg.removeChild(svg.firstChild);
  const est = data.estimates || [];
  const latest = est[est.length - 1];
  const model = data.model;
  svg.dataset.period = latest ? String(latest.period) : '0';
  svg.dataset.estimates = String(est.length);
  svg.dataset.points = latest ? String(latest.freq_hz.length) : '0';
  svg.dataset.model = model ? '1' : '0';
  if (!latest) {
    text(svg, 480, 300, 'The Bode estimate appears here after the first measured period.',
      { 'text-anchor': 'middle', class: 'empty' });
    return;
  }
  const fs = latest.freq_hz.filter((f) => f > 0);
  const fLo = Math.pow(10, Math.floor(Math.log10(Math.min(...fs)) * 10) / 10);
  const fHi = Math.pow(10, Math.ceil(Math.log10(Math.max(...fs)) * 10) / 10);
  const sx = (f) => PLOT.left + (Math.log10(f) - Math.log10(fLo)) /
    (Math.log10(fHi) - Math.log10(fLo)) * (PLOT.right - PLOT.left);

  // the uncertainty band of the latest magnitude: 20 log10(1 -/+ relative std)
  const bandLo = latest.magnitude_db.map((m, i) => {
    const r = latest.relative_std[i];
    return r < 0.99 ? m + 20 * Math.log10(1 - r) : NaN;
  });
  const bandHi = latest.magnitude_db.map((m, i) => m + 20 * Math.log10(1 + latest.relative_std[i]));

  const series = {
    mag: { get: (e) => e.magnitude_db, model: model && model.magnitude_db, step: 10, span: 20 },
    phase: { get: (e) => e.phase_deg, model: model && model.phase_deg, step: 45, span: 90, tick: 90 },
    coh: { get: (e) => e.coherence, model: null, fixed: [0, 1] },
  };
  for (const p of PLOT.panels) {
    const s = series[p.key];
    const [yLo, yHi] = s.fixed || range([s.get(latest), s.model], s.step, s.span);
    const sy = (v) => p.bottom - (Math.min(Math.max(v, yLo), yHi) - yLo) / (yHi - yLo) * (p.bottom - p.top);
    const g = el('g', { 'data-panel': p.key }, svg);
    drawGrid(g, p, fLo, fHi, sx, yLo, yHi, sy, s.fixed ? 0.25 : s.tick || niceStep(yLo, yHi, 5));
    // earlier estimates (at most 8), faint
    for (const e of est.slice(Math.max(0, est.length - 9), -1)) {
      const ys = s.get(e);
      if (ys) el('path', { d: pathD(e.freq_hz, ys, sx, sy), class: 'history' }, g);
    }
    if (p.key === 'mag') el('path', { d: bandD(latest.freq_hz, bandLo, bandHi, sx, sy), class: 'band' }, g);
    const ys = s.get(latest);
    if (ys) {
      el('path', { d: pathD(latest.freq_hz, ys, sx, sy), class: 'measured', 'data-trace': 'measured' }, g);
    } else {
      text(g, (PLOT.left + PLOT.right) / 2, (p.top + p.bottom) / 2,
        'coherence from the second measured period on', { 'text-anchor': 'middle', class: 'empty' });
    }
    if (s.model) el('path', { d: pathD(model.freq_hz, s.model, sx, sy), class: 'model', 'data-trace': 'model' }, g);
    el('rect', { x: PLOT.left, y: p.top, width: PLOT.right - PLOT.left, height: p.bottom - p.top, class: 'frame' }, g);
    text(g, 16, (p.top + p.bottom) / 2, p.label,
      { transform: `rotate(-90 16 ${(p.top + p.bottom) / 2})`, 'text-anchor': 'middle' });
  }
  text(svg, (PLOT.left + PLOT.right) / 2, 614, PLOT.xLabel, { 'text-anchor': 'middle' });
}

function drawGrid(g, p, fLo, fHi, sx, yLo, yHi, sy, yStep) {
  // log x: a line at every 1..9 x 10^k, labels at 1, 2, 5 x 10^k
  for (let k = Math.floor(Math.log10(fLo)); k <= Math.ceil(Math.log10(fHi)); k++) {
    for (let m = 1; m <= 9; m++) {
      const f = m * Math.pow(10, k);
      if (f < fLo * 0.999 || f > fHi * 1.001) continue;
      const x = sx(f);
      el('line', { x1: x, x2: x, y1: p.top, y2: p.bottom, class: m === 1 ? 'grid major' : 'grid' }, g);
      if (m === 1 || m === 2 || m === 5) {
        text(g, x, p.bottom + 14, fmtHz(f), { 'text-anchor': 'middle' });
      }
    }
  }
  for (const v of linTicks(yLo, yHi, yStep)) {
    const y = sy(v);
    el('line', { x1: PLOT.left, x2: PLOT.right, y1: y, y2: y, class: 'grid major' }, g);
    text(g, PLOT.left - 6, y + 4, String(v), { 'text-anchor': 'end' });
  }
}

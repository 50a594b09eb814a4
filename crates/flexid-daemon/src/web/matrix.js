// The N x N Bode matrix of the daemon page (a robot's multi-axis sweep): one magnitude
// plot per element, output (motor speed) i in row i, input (motor torque) j in column j,
// over a shared logarithmic frequency axis [Hz]; the measured magnitude with its one-sigma
// band and, after an identification, the model's. Uses el(), text(), pathD(), bandD() and
// fmtHz() of bode.js. No dependencies.
'use strict';

/** Layout of the matrix inside its view box. */
const MATRIX = { size: 960, left: 64, top: 30, right: 950, bottom: 920, gap: 8 };

/**
 * Draw into `svg`.
 * data = { frf: frf_matrix.json | null, model: {freq_hz, magnitude_db} | null, title }
 */
function drawBodeMatrix(svg, data) {
  while (svg.firstChild) svg.removeChild(svg.firstChild);
  const frf = data.frf;
  const model = data.model;
  const n = frf ? frf.magnitude_db.length : 0;
  svg.dataset.axes = String(n);
  svg.dataset.lines = frf ? String(frf.freq_hz.length) : '0';
  svg.dataset.model = model ? '1' : '0';
  if (!frf) {
    text(svg, MATRIX.size / 2, 300, data.empty || 'The FRF matrix appears here when a multi-axis sweep ends.',
      { 'text-anchor': 'middle', class: 'empty' });
    return;
  }
  const fs = frf.freq_hz.filter((f) => f > 0);
  const fLo = Math.pow(10, Math.floor(Math.log10(Math.min(...fs))));
  const fHi = Math.pow(10, Math.ceil(Math.log10(Math.max(...fs))));
  const cw = (MATRIX.right - MATRIX.left - (n - 1) * MATRIX.gap) / n;
  const ch = (MATRIX.bottom - MATRIX.top - (n - 1) * MATRIX.gap) / n;
  // one magnitude range for all: the elements compare (the off-diagonal ones are weak)
  let hi = -Infinity;
  for (const row of frf.magnitude_db) for (const m of row) for (const v of m) if (v > -399) hi = Math.max(hi, v);
  const yHi = Math.ceil(hi / 20) * 20;
  const yLo = yHi - 120;
  text(svg, MATRIX.size / 2, 16, data.title || '', { 'text-anchor': 'middle', class: 'title' });
  for (let i = 0; i < n; i++) {
    for (let j = 0; j < n; j++) {
      const x0 = MATRIX.left + j * (cw + MATRIX.gap);
      const y0 = MATRIX.top + i * (ch + MATRIX.gap);
      const sx = (f) => x0 + (Math.log10(f) - Math.log10(fLo)) / (Math.log10(fHi) - Math.log10(fLo)) * cw;
      const sy = (v) => y0 + ch - (Math.min(Math.max(v, yLo), yHi) - yLo) / (yHi - yLo) * ch;
      const g = el('g', { 'data-element': `${i + 1},${j + 1}`, class: i === j ? 'diag' : 'off' }, svg);
      for (let k = Math.log10(fLo); k <= Math.log10(fHi) + 1e-9; k++) {
        const x = sx(Math.pow(10, k));
        el('line', { x1: x, x2: x, y1: y0, y2: y0 + ch, class: 'grid major' }, g);
        // the left edge's label only in the first column (it would meet the previous cell's right one)
        const edge = k <= Math.log10(fLo) + 1e-9;
        if (i === n - 1 && (j === 0 || !edge)) text(g, x, y0 + ch + 12, fmtHz(Math.pow(10, k)), { 'text-anchor': 'middle' });
      }
      for (let v = yLo; v <= yHi; v += 40) {
        const y = sy(v);
        el('line', { x1: x0, x2: x0 + cw, y1: y, y2: y, class: 'grid' }, g);
        if (j === 0) text(g, x0 - 4, y + 4, String(v), { 'text-anchor': 'end' });
      }
      const mag = frf.magnitude_db[i][j];
      // the one-sigma band: |G| -/+ sigma, sigma = sqrt(var) of the complex estimate
      const sd = frf.var.map((v) => Math.sqrt(v[i][j]));
      const abs = mag.map((m) => Math.pow(10, m / 20));
      const lo = abs.map((a, k) => (a > sd[k] ? 20 * Math.log10(a - sd[k]) : yLo));
      const up = abs.map((a, k) => 20 * Math.log10(a + sd[k]));
      el('path', { d: bandD(frf.freq_hz, lo, up, sx, sy), class: 'band' }, g);
      el('path', { d: pathD(frf.freq_hz, mag, sx, sy), class: 'measured', 'data-trace': 'measured' }, g);
      if (model) {
        el('path', { d: pathD(model.freq_hz, model.magnitude_db[i][j], sx, sy), class: 'model', 'data-trace': 'model' }, g);
      }
      el('rect', { x: x0, y: y0, width: cw, height: ch, class: 'frame' }, g);
      text(g, x0 + cw - 4, y0 + 12, `G${i + 1}${j + 1}`, { 'text-anchor': 'end', class: 'label' });
    }
  }
  text(svg, 14, (MATRIX.top + MATRIX.bottom) / 2, '|G| [dB re 1 (rad/s)/(N m)], row: motor speed, column: motor torque',
    { transform: `rotate(-90 14 ${(MATRIX.top + MATRIX.bottom) / 2})`, 'text-anchor': 'middle' });
  text(svg, (MATRIX.left + MATRIX.right) / 2, MATRIX.size - 8, 'frequency [Hz]', { 'text-anchor': 'middle' });
}

// The daemon page: token login, axis and sweep form, start/abort, the live event stream
// (fetch streaming: EventSource cannot send the Authorization header), the Bode plot
// (bode.js) and the parameter table.
'use strict';

const TOKEN_KEY = 'flexid.token';
const $ = (id) => document.getElementById(id);

const state = {
  token: sessionStorage.getItem(TOKEN_KEY) || '',
  axes: [],
  sweepId: null,     // the sweep shown
  running: false,
  stream: null,      // AbortController of the event stream
  estimates: [],     // bode events of the shown sweep, oldest first
  model: null,       // model_bode of the result
};

class ApiError extends Error {
  constructor(status, body) {
    super((body && body.error) || `HTTP ${status}`);
    this.status = status;
    this.field = body && body.field;
  }
}

/** A request to the API with the token; JSON errors become ApiError. */
async function api(path, opts) {
  const o = Object.assign({}, opts || {});
  o.headers = Object.assign({ Authorization: 'Bearer ' + state.token }, o.headers || {});
  o.cache = 'no-store';
  const r = await fetch(path, o);
  if (!r.ok) {
    let body = null;
    try { body = await r.json(); } catch (_) { /* not JSON */ }
    if (r.status === 401) loggedOut('the daemon refused the token');
    throw new ApiError(r.status, body);
  }
  return r;
}

function say(msg, bad) {
  $('message').textContent = msg || '';
  $('message').className = bad ? 'bad' : '';
}

// ---- login -----------------------------------------------------------------------------

function loggedOut(why) {
  state.token = '';
  sessionStorage.removeItem(TOKEN_KEY);
  $('login-state').textContent = why || 'not connected';
  $('login-state').className = why ? 'bad' : '';
  $('logout').hidden = true;
  $('axis').disabled = true;
  $('start').disabled = true;
  $('robot').hidden = true;
}

async function connect() {
  if (!state.token) return loggedOut();
  try {
    await refreshAxes();
  } catch (e) {
    if (!(e instanceof ApiError && e.status === 401)) {
      $('login-state').textContent = 'cannot reach the daemon: ' + e.message;
      $('login-state').className = 'bad';
    }
    return;
  }
  sessionStorage.setItem(TOKEN_KEY, state.token);
  $('login-state').textContent = 'connected';
  $('login-state').className = '';
  $('logout').hidden = false;
  $('token').value = '';
  $('axis').disabled = false;
  followRunningSweep();
  robotConnect();
}

// ---- axes ------------------------------------------------------------------------------

async function refreshAxes() {
  const r = await api('/api/v1/axes');
  const body = await r.json();
  state.axes = body.axes || [];
  state.robot = body.robot || null;
  const sel = $('axis');
  const keep = sel.value;
  sel.replaceChildren(...state.axes.map((a) => {
    const o = document.createElement('option');
    o.value = a.name;
    o.textContent = `${a.name} (${a.state})`;
    return o;
  }));
  if (state.axes.some((a) => a.name === keep)) sel.value = keep;
  showAxis();
}

function selectedAxis() {
  return state.axes.find((a) => a.name === $('axis').value);
}

function showAxis() {
  const a = selectedAxis();
  if (!a) { $('axis-info').textContent = 'no axis configured'; return; }
  const kind = a.bus_kind === 'ethercat' ? 'EtherCAT' : `CAN (${a.bus_kind})`;
  const where = a.bus_kind === 'ethercat' ? `SubDevice ${a.node}` : `node ${a.node}`;
  $('axis-info').textContent = `bus ${a.bus}: ${kind}, ${where}, cycle ${a.cycle_hz} Hz ` +
    `(band below ${a.cycle_hz / 2} Hz), ${a.state}`;
  $('band-hi').max = String(a.cycle_hz / 2);
  updateButtons();
}

function updateButtons() {
  const a = selectedAxis();
  $('start').disabled = !state.token || !a || a.state !== 'idle' || state.running;
  $('abort').disabled = !state.running;
}

/** When the chosen axis is sweeping (e.g. started elsewhere), show that sweep. */
function followRunningSweep() {
  const a = selectedAxis();
  if (a && a.sweep_id && a.sweep_id !== state.sweepId) follow(a.sweep_id);
}

// ---- sweep -----------------------------------------------------------------------------

const FIELDS = {
  excitation: ['excitation'], band_hz: ['band-lo', 'band-hi'], amplitude_nm: ['amplitude'],
  periods: ['periods'], duration_s: ['duration'],
};

/** The number in an input, or its text when it is none (the daemon names the bad field). */
function num(id) {
  const v = $(id).value.trim();
  return v !== '' && Number.isFinite(Number(v)) ? Number(v) : v;
}

async function startSweep() {
  const a = selectedAxis();
  if (!a) return;
  for (const ids of Object.values(FIELDS)) for (const id of ids) $(id).removeAttribute('aria-invalid');
  const body = {
    excitation: $('excitation').value,
    band_hz: [num('band-lo'), num('band-hi')],
    amplitude_nm: num('amplitude'),
    periods: num('periods'),
    duration_s: num('duration'),
  };
  say('starting…');
  try {
    const r = await api(`/api/v1/axes/${encodeURIComponent(a.name)}/sweeps`, {
      method: 'POST',
      headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify(body),
    });
    const started = await r.json();
    say(`sweep ${started.sweep_id} started on ${a.name}`);
    follow(started.sweep_id);
    refreshAxes().catch(() => {});
  } catch (e) {
    say('refused: ' + e.message, true);
    for (const id of FIELDS[e.field] || []) $(id).setAttribute('aria-invalid', 'true');
  }
}

async function abortSweep() {
  if (!state.sweepId) return;
  try {
    await api(`/api/v1/sweeps/${encodeURIComponent(state.sweepId)}/abort`, { method: 'POST' });
    say('aborting: the torque ramps to zero, the recording is kept');
  } catch (e) {
    say('abort: ' + e.message, true);
  }
}

// ---- the event stream ------------------------------------------------------------------

/** Show sweep `id`: reset the view and read its events until `ended`. */
async function follow(id) {
  if (state.stream) state.stream.abort();
  const ctl = new AbortController();
  Object.assign(state, { sweepId: id, running: true, stream: ctl, estimates: [], model: null });
  $('result').hidden = true;
  $('state').textContent = 'running';
  $('period-text').textContent = '';
  $('counters').textContent = '';
  $('progress').value = 0;
  redraw();
  updateButtons();
  try {
    const r = await api(`/api/v1/sweeps/${encodeURIComponent(id)}/events`, { signal: ctl.signal });
    const reader = r.body.pipeThrough(new TextDecoderStream()).getReader();
    let buf = '';
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      buf = (buf + value).replace(/\r\n/g, '\n');
      let end;
      while ((end = buf.indexOf('\n\n')) >= 0) {
        const ev = parseEvent(buf.slice(0, end));
        buf = buf.slice(end + 2);
        if (ev && state.sweepId === id) onEvent(ev.name, ev.data);
      }
    }
  } catch (e) {
    if (e.name !== 'AbortError') say('event stream: ' + e.message, true);
  }
  if (state.sweepId === id) {
    state.running = false;
    state.stream = null;
    refreshAxes().catch(() => {});
    updateButtons();
  }
}

/** One server-sent event block -> {name, data} (null for keep-alive comments). */
function parseEvent(block) {
  let name = 'message', data = '';
  for (const line of block.split('\n')) {
    if (line.startsWith('event:')) name = line.slice(6).trim();
    else if (line.startsWith('data:')) data += line.slice(5).replace(/^ /, '');
  }
  if (!data) return null;
  try { return { name, data: JSON.parse(data) }; } catch (_) { return null; }
}

function onEvent(name, d) {
  if (name === 'progress') {
    $('progress').max = d.periods_total;
    $('progress').value = d.period;
    $('period-text').textContent =
      `period ${d.period} of ${d.periods_total} (the first is the transient) · ` +
      `${d.elapsed_s.toFixed(1)} of ${d.planned_s.toFixed(1)} s`;
    const c = d.counters || {};
    $('counters').textContent = `cycles ${c.cycles ?? '–'}, late ${c.late ?? '–'}, lost ${c.lost ?? '–'}`;
  } else if (name === 'bode') {
    state.estimates.push(d);
    redraw();
  } else if (name === 'result') {
    state.model = d.model_bode || null;
    showParams(d);
    redraw();
  } else if (name === 'ended') {
    state.running = false;
    $('state').textContent = d.outcome;
    const out = $('outcome');
    out.dataset.outcome = d.outcome;
    out.className = d.outcome;
    out.textContent = d.outcome === 'completed'
      ? `completed · ${d.samples} samples`
      : `${d.outcome}: ${d.reason} · ${d.samples} samples kept`;
    $('result').hidden = false;
    updateButtons();
  }
}

function redraw() {
  drawBode($('bode'), { estimates: state.estimates, model: state.model });
}

// ---- the result ------------------------------------------------------------------------

function fmt(v) {
  return Number.isFinite(v) ? v.toPrecision(4) : '–';
}

function showParams(r) {
  const body = $('params').tBodies[0];
  body.replaceChildren();
  const m = r.model;
  const row = (name, v, s, unit) => {
    const tr = body.insertRow();
    // null, or an uncertainty above the value: the data do not identify the parameter
    const known = Number.isFinite(v) && Number.isFinite(s) && s <= Math.abs(v);
    const cells = known
      ? [name, fmt(v), `${fmt(s)} (${(100 * s / Math.abs(v)).toFixed(1)} %)`, unit]
      : [name, 'not identifiable', '–', unit];
    cells.forEach((c, i) => {
      const td = tr.insertCell();
      td.textContent = c;
      if (i === 1 || i === 2) td.className = 'num';
    });
  };
  if (m) {
    m.inertia_kgm2.forEach((v, i) =>
      row(`J${i + 1}${i === 0 ? ' (motor)' : ''} inertia`, v, m.inertia_std_kgm2[i], 'kg m²'));
    m.stiffness_nm_per_rad.forEach((v, i) =>
      row(`c${i + 1} stiffness`, v, m.stiffness_std_nm_per_rad[i], 'N m/rad'));
    m.damping_nms_per_rad.forEach((v, i) =>
      row(`d${i + 1} damping`, v, m.damping_std_nms_per_rad[i], 'N m s/rad'));
    const hz = (a) => (a || []).map((f) => (Number.isFinite(f) ? f.toFixed(1) : 'not identifiable')).join(', ') || '–';
    $('modes').textContent = `${m.masses} masses · resonances ${hz(m.resonance_hz)} Hz · ` +
      `anti-resonances ${hz(m.antiresonance_hz)} Hz · total inertia ${fmt(m.total_inertia_kgm2)} kg m²`;
  } else {
    $('modes').textContent = 'no model identified' + (r.error ? ': ' + r.error : '');
  }
  $('params').hidden = !m;
  $('notes').textContent = (r.notes || []).join(' ');
}

/** Downloads need the token header too: fetch, then save the blob. */
async function download(file) {
  if (!state.sweepId) return;
  try {
    const r = await api(`/api/v1/sweeps/${encodeURIComponent(state.sweepId)}/${file}`);
    const url = URL.createObjectURL(await r.blob());
    const a = document.createElement('a');
    a.href = url;
    a.download = `${state.sweepId}-${file}`;
    a.click();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
  } catch (e) {
    say(`${file}: ${e.message}`, true);
  }
}

// ---- wiring ----------------------------------------------------------------------------

document.addEventListener('DOMContentLoaded', () => {
  $('login').addEventListener('submit', (ev) => {
    ev.preventDefault();
    state.token = $('token').value.trim();
    connect();
  });
  $('logout').addEventListener('click', () => loggedOut());
  $('axis').addEventListener('change', () => { showAxis(); followRunningSweep(); });
  $('sweep-form').addEventListener('submit', (ev) => { ev.preventDefault(); startSweep(); });
  $('abort').addEventListener('click', abortSweep);
  for (const b of document.querySelectorAll('#downloads button')) {
    b.addEventListener('click', () => download(b.dataset.file));
  }
  redraw();
  if (state.token) connect();
});

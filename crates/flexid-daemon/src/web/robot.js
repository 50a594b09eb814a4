// The robot section of the daemon page: a multi-axis sweep at a pose of the robot's file,
// its progress (the job polled), the N x N Bode matrix (matrix.js) when it ends, the
// identification of the flexibilities and their table, the model overlaid on the matrix.
// Uses api(), $ and fmt() of app.js.
'use strict';

const robot = {
  info: null,      // GET /api/v1/robot
  job: null,       // the job followed
  frf: null,       // frf_matrix.json of the sweep shown
  frfJob: null,    // its job id
  model: null,     // {freq_hz, magnitude_db} of the identified model at the shown sweep's pose
  timer: null,
};

function robotSay(msg, bad) {
  $('robot-notes').textContent = msg || '';
  $('robot-notes').className = bad ? 'bad' : '';
}

/** After login: show the section when a robot is configured. */
async function robotConnect() {
  if (!state.robot) {
    $('robot').hidden = true;
    return;
  }
  try {
    const r = await api('/api/v1/robot');
    robot.info = await r.json();
  } catch (e) {
    $('robot').hidden = true;
    return;
  }
  const info = robot.info;
  $('robot').hidden = false;
  $('robot-name').textContent = `${info.name} (${info.model})`;
  $('robot-info').textContent = `${info.axes} axes, nodes ${info.nodes.join(', ')}, cycle ` +
    `${info.cycle_hz} Hz, ${info.backend}; ${info.parameters.length} flexibility parameters`;
  const sel = $('robot-pose');
  sel.replaceChildren(...info.poses.map((p) => {
    const o = document.createElement('option');
    o.value = p.name;
    o.textContent = `${p.name} (${p.role}) [${p.q_deg.join(', ')}]°`;
    return o;
  }));
  const latest = (info.jobs || []).filter((j) => j.kind === 'sweep' && j.state === 'completed')
    .sort((a, b) => b.started_unix_s - a.started_unix_s)[0];
  if (info.running) robotFollow(info.running);
  else if (latest && !robot.frf) robotShowSweep(latest.id);
  robotDraw();
  robotButtons();
}

function robotButtons() {
  const busy = robot.job && robot.job.state === 'running';
  $('robot-sweep').disabled = !state.token || busy;
  $('robot-identify').disabled = !state.token || busy;
  $('robot-abort').disabled = !busy;
}

function robotDraw() {
  const title = robot.frf ? `${robot.frf.robot} at pose ${robot.frf.pose}: motor torques to motor speeds` : '';
  drawBodeMatrix($('bode-matrix'), { frf: robot.frf, model: robot.model, title });
}

async function robotStart(path, body, what) {
  robotSay(`starting ${what}…`);
  try {
    const r = await api(path, {
      method: 'POST',
      headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify(body),
    });
    const started = await r.json();
    robotSay(`${what} ${started.job_id} started`);
    robotFollow(started.job_id);
  } catch (e) {
    robotSay(`${what} refused: ${e.message}`, true);
  }
}

/** Poll job `id` until it ends, showing its progress; then show what it produced. */
function robotFollow(id) {
  if (robot.timer) clearInterval(robot.timer);
  const tick = async () => {
    let job;
    try {
      job = await (await api(`/api/v1/robot/jobs/${encodeURIComponent(id)}`)).json();
    } catch (e) {
      robotSay('job: ' + e.message, true);
      clearInterval(robot.timer);
      return;
    }
    robot.job = job;
    $('robot-state').textContent = `${job.kind} ${job.state}`;
    if (job.kind === 'sweep' && job.cycles === 0) {
      $('robot-progress').removeAttribute('value');
      $('robot-text').textContent = `pose ${job.pose} · bringing the drives up`;
    } else if (job.kind === 'sweep') {
      $('robot-progress').max = Math.max(1, job.cycles);
      $('robot-progress').value = job.cycle;
      $('robot-text').textContent = `pose ${job.pose} · experiment ${Math.min(job.experiment + 1, job.experiments)} ` +
        `of ${job.experiments} · cycle ${job.cycle} of ${job.cycles} · ${job.elapsed_s.toFixed(1)} s`;
    } else {
      $('robot-progress').removeAttribute('value');
      $('robot-text').textContent = `${job.message} · ${job.elapsed_s.toFixed(1)} s`;
    }
    robotButtons();
    if (job.state === 'running') return;
    clearInterval(robot.timer);
    robot.timer = null;
    $('robot-progress').max = 1;
    $('robot-progress').value = 1;
    $('robot-text').textContent = job.message;
    robotSay(job.state === 'completed' ? '' : `${job.kind} ${job.state}: ${job.message}`, job.state !== 'completed');
    if (job.state !== 'completed') return;
    if (job.kind === 'sweep') await robotShowSweep(job.id);
    else await robotShowIdentification(job.id);
  };
  robot.timer = setInterval(tick, 300);
  tick();
}

async function robotShowSweep(id) {
  try {
    robot.frf = await (await api(`/api/v1/robot/jobs/${encodeURIComponent(id)}/frf_matrix.json`)).json();
    robot.frfJob = id;
    robot.model = null;
    robotDraw();
  } catch (e) {
    robotSay('FRF matrix: ' + e.message, true);
  }
}

async function robotShowIdentification(id) {
  let r;
  try {
    r = await (await api(`/api/v1/robot/jobs/${encodeURIComponent(id)}/identification.json`)).json();
  } catch (e) {
    robotSay('identification: ' + e.message, true);
    return;
  }
  const body = $('robot-params').tBodies[0];
  body.replaceChildren();
  for (const p of r.parameters) {
    const tr = body.insertRow();
    tr.dataset.name = p.name;
    tr.dataset.value = String(p.value);
    const known = p.identifiable === true && Number.isFinite(p.std_rel);
    const cells = [p.name, known ? fmt(p.value) : 'not identifiable', fmt(p.nominal),
      known ? `${(100 * p.std_rel).toPrecision(2)} %` : '–', p.unit];
    cells.forEach((c, i) => {
      const td = tr.insertCell();
      td.textContent = c;
      if (i >= 1 && i <= 3) td.className = 'num';
    });
  }
  $('robot-params').hidden = false;
  robotSay(`V ${r.cost_db.toFixed(3)} dB over ${r.sweeps.length} poses; ${r.good_starts} of ` +
    `${r.starts.length} starts reached the best cost`);
  // the model over the measurement of a pose it was fitted to (the shown one if it was)
  let m = r.models.find((x) => x.sweep === robot.frfJob);
  if (!m) {
    m = r.models[0];
    await robotShowSweep(m.sweep);
  }
  robot.model = m;
  robotDraw();
}

document.addEventListener('DOMContentLoaded', () => {
  $('robot-form').addEventListener('submit', (ev) => {
    ev.preventDefault();
    robotStart('/api/v1/robot/sweeps', { pose: $('robot-pose').value }, 'multi-axis sweep');
  });
  $('robot-identify').addEventListener('click', () =>
    robotStart('/api/v1/robot/identifications', {}, 'identification'));
  $('robot-abort').addEventListener('click', async () => {
    if (!robot.job) return;
    try {
      await api(`/api/v1/robot/jobs/${encodeURIComponent(robot.job.id)}/abort`, { method: 'POST' });
      robotSay('aborting: the torques ramp to zero');
    } catch (e) {
      robotSay('abort: ' + e.message, true);
    }
  });
  robotDraw();
});

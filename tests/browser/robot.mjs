// The daemon page's robot section in headless chromium (run by tests/daemon_web.rs):
//   FLEXID_URL=http://127.0.0.1:PORT FLEXID_TOKEN=... FLEXID_SCREENSHOT=out.png node robot.mjs
// 1. login: the robot section appears with its poses;
// 2. a multi-axis sweep at pose id-1: progress, then the N x N Bode matrix (screenshot);
// 3. a sweep at pose id-2, then the identification: the parameter table and the model
//    drawn over every element of the matrix (screenshot).
// Prints one `browser: ...` line per observation; exits non-zero on the first failure.
import { check, daemonEnv, log, runPage } from './harness.mjs';

const { url, token, shot } = daemonEnv();

await runPage({ width: 1200, height: 1400, httpErrors: true }, async (page) => {
  await page.goto(url + '/');
  await page.fill('#token', token);
  await page.click('#connect');
  await page.waitForFunction(() => !document.getElementById('robot').hidden, null, { timeout: 20000 });
  const poses = await page.$$eval('#robot-pose option', (os) => os.map((o) => o.value));
  log('robot:', await page.textContent('#robot-name'), '| poses:', poses.join(', '));
  check(poses.includes('id-1') && poses.includes('id-2'), 'identification poses listed');
  check(await page.$eval('#bode-matrix', (s) => s.dataset.axes) === '0', 'no matrix before a sweep');

  const sweepAt = async (pose) => {
    await page.waitForFunction(() => !document.getElementById('robot-sweep').disabled, null, { timeout: 30000 });
    await page.selectOption('#robot-pose', pose);
    await page.click('#robot-sweep');
    // progress while it runs: the bar moves
    await page.waitForFunction(() => /experiment [1-9]\d* of \d+/.test(document.getElementById('robot-text').textContent),
      null, { timeout: 30000 });
    log(`sweep at ${pose}:`, await page.textContent('#robot-text'));
    await page.waitForFunction((p) => {
      const s = document.getElementById('bode-matrix');
      return s.dataset.axes !== '0' && /completed/.test(document.getElementById('robot-state').textContent)
        && s.querySelector('text.title') && s.querySelector('text.title').textContent.includes(p);
    }, pose, { timeout: 300000 });
    const m = await page.$eval('#bode-matrix', (s) => ({
      axes: Number(s.dataset.axes), lines: Number(s.dataset.lines), model: s.dataset.model,
      cells: s.querySelectorAll('g[data-element]').length,
      traces: [...s.querySelectorAll('path.measured')].filter((p) => p.getAttribute('d').length > 200).length,
    }));
    log(`matrix at ${pose}: ${m.axes} x ${m.axes}, ${m.cells} cells, ${m.traces} measured traces, ${m.lines} lines`);
    check(m.axes === 6 && m.cells === 36, '6 x 6 elements drawn');
    check(m.traces === 36, 'a measured trace in every element');
    check(m.lines > 100, 'lines plotted');
    return m;
  };

  await sweepAt('id-1');
  await page.locator('#robot').screenshot({ path: shot });
  log('screenshot', shot);
  await sweepAt('id-2');

  await page.click('#robot-identify');
  await page.waitForFunction(() => document.getElementById('bode-matrix').dataset.model === '1',
    null, { timeout: 300000 });
  const models = await page.$$eval('#bode-matrix path.model', (ps) => ps.filter((p) => p.getAttribute('d').length > 200).length);
  log(`model drawn over ${models} elements;`, await page.textContent('#robot-notes'));
  check(models === 36, 'the model over every element');
  const rows = await page.$$eval('#robot-params tbody tr', (trs) => trs.map((tr) => ({
    name: tr.dataset.name, value: Number(tr.dataset.value), cells: [...tr.cells].map((c) => c.textContent),
  })));
  for (const r of rows) log('param:', r.cells.join(' | '));
  check(rows.length === 24, '24 parameters');
  check(rows.every((r) => r.cells[4] === 'N m/rad' || r.cells[4] === 'N m s/rad'), 'units shown');
  check(rows.every((r) => r.cells[1] !== 'not identifiable'), 'all identified');
  console.log('browser: result ' + rows.slice(0, 12).map((r) => `${r.name}=${r.value}`).join(' '));
  const shotDone = shot.replace(/\.png$/, '') + '-identified.png';
  await page.locator('#robot').screenshot({ path: shotDone });
  log('screenshot', shotDone);
});

// The daemon's web page in headless chromium (run by tests/daemon_web.rs):
//   FLEXID_URL=http://127.0.0.1:PORT FLEXID_TOKEN=... FLEXID_SCREENSHOT=out.png \
//   FLEXID_LIVE_AXIS=slow FLEXID_DONE_AXIS=fast node bode.mjs
// 1. a wrong token is refused; the right one lists the axes;
// 2. a sweep on the real-time axis: the Bode plot grows period by period (screenshot),
//    abort, the aborted reason is shown;
// 3. a sweep on the simulated-clock axis to its end: the identified model over the
//    measurement and the parameter table with numbers.
// Prints one `browser: ...` line per observation; exits non-zero on the first failure.
import { check, daemonEnv, log, runPage } from './harness.mjs';

const { url, token, shot } = daemonEnv();
const liveAxis = process.env.FLEXID_LIVE_AXIS || 'slow';
const doneAxis = process.env.FLEXID_DONE_AXIS || 'fast';

await runPage({ width: 1200, height: 1100 }, async (page, errors) => {
  await page.goto(url + '/');
  check((await page.title()).includes('flexid'), 'page title');

  // a wrong token: refused, no axes
  await page.fill('#token', 'not-the-token');
  await page.click('#connect');
  await page.waitForFunction(() => /refused/.test(document.getElementById('login-state').textContent));
  check(await page.locator('#axis option').count() === 0, 'no axes without the token');
  log('wrong token refused:', await page.textContent('#login-state'));
  errors.length = 0; // the 401 itself is logged by chromium as a failed resource

  // the token: axes listed
  await page.fill('#token', token);
  await page.click('#connect');
  await page.waitForFunction(() => document.querySelectorAll('#axis option').length > 0);
  const axes = await page.$$eval('#axis option', (os) => os.map((o) => o.value));
  log('axes:', axes.join(', '));
  check(axes.includes(liveAxis) && axes.includes(doneAxis), 'both axes listed');

  // live sweep: watch it grow, screenshot, abort
  await page.selectOption('#axis', liveAxis);
  await page.selectOption('#excitation', 'multisine');
  await page.fill('#band-lo', '2');
  await page.fill('#band-hi', '200');
  await page.fill('#amplitude', '0.5');
  await page.fill('#periods', '9');
  await page.fill('#duration', '20');
  await page.click('#start');
  const period = () => page.$eval('#bode', (s) => Number(s.dataset.period));
  await page.waitForFunction(() => Number(document.getElementById('bode').dataset.period) >= 2,
    null, { timeout: 30000 });
  const first = { period: await period(), estimates: await page.$eval('#bode', (s) => Number(s.dataset.estimates)) };
  await page.waitForFunction((p) => Number(document.getElementById('bode').dataset.period) > p,
    first.period, { timeout: 30000 });
  const second = { period: await period(), estimates: await page.$eval('#bode', (s) => Number(s.dataset.estimates)) };
  const points = await page.$eval('#bode', (s) => Number(s.dataset.points));
  log(`bode grew: period ${first.period} -> ${second.period}, estimates drawn ${first.estimates} -> ${second.estimates}, ${points} lines`);
  check(second.estimates > first.estimates, 'more estimates drawn');
  check(points > 50, 'lines plotted');
  const measuredPaths = await page.$$eval('#bode path.measured', (ps) => ps.filter((p) => p.getAttribute('d').length > 100).length);
  check(measuredPaths >= 2, 'magnitude and phase traces drawn');
  await page.screenshot({ path: shot, fullPage: true });
  log('screenshot', shot);
  check(await page.isEnabled('#abort'), 'abort enabled while running');
  await page.click('#abort');
  await page.waitForFunction(() => document.getElementById('outcome').dataset.outcome !== '',
    null, { timeout: 30000 });
  const aborted = await page.textContent('#outcome');
  log('after abort:', aborted);
  check(/aborted/.test(aborted) && /operator abort/.test(aborted), 'aborted reason shown');

  // a sweep to its end: model over the measurement, parameter table
  await page.selectOption('#axis', doneAxis);
  await page.waitForFunction(() => !document.getElementById('start').disabled, null, { timeout: 30000 });
  await page.fill('#periods', '4');
  await page.fill('#duration', '5');
  await page.click('#start');
  await page.waitForFunction(() => document.getElementById('outcome').dataset.outcome === 'completed',
    null, { timeout: 60000 });
  await page.waitForFunction(() => document.querySelectorAll('#params tbody tr').length > 0);
  const rows = await page.$$eval('#params tbody tr', (trs) => trs.map((tr) => [...tr.cells].map((c) => c.textContent)));
  for (const r of rows) log('param:', r.join(' | '));
  const value = (prefix) => Number((rows.find((r) => r[0].startsWith(prefix)) || [])[1]);
  check(rows.length >= 4, 'J1, J2, c1, d1 rows');
  for (const p of ['J1', 'J2', 'c1']) check(Number.isFinite(value(p)) && value(p) > 0, `${p} is a positive number`);
  check(rows.every((r) => r[3].length > 0), 'units shown');
  check(await page.$eval('#bode', (s) => s.dataset.model) === '1', 'model drawn over the measurement');
  check(await page.locator('#bode path.model').count() === 2, 'model magnitude and phase');
  console.log(`browser: result J1=${value('J1')} J2=${value('J2')} c1=${value('c1')}`);
  const shotDone = shot.replace(/\.png$/, '') + '-result.png';
  await page.screenshot({ path: shotDone, fullPage: true });
  log('screenshot', shotDone);
});

// The daemon page with an EtherCAT axis in headless chromium (run by tests/daemon_ethercat.rs):
//   FLEXID_URL=http://127.0.0.1:PORT FLEXID_TOKEN=... FLEXID_SCREENSHOT=out.png \
//   FLEXID_AXIS=e1 node ethercat.mjs
// 1. login: the axis is listed, its line says EtherCAT, its SubDevice and its cycle rate;
// 2. a multisine sweep to its end from the page: the identified model over the measurement
//    and the parameter table with numbers and units (screenshot).
// Prints one `browser: ...` line per observation; exits non-zero on the first failure.
import { check, daemonEnv, log, runPage } from './harness.mjs';

const { url, token, shot } = daemonEnv();
const axis = process.env.FLEXID_AXIS || 'e1';

await runPage({ width: 1200, height: 1100, httpErrors: true }, async (page) => {
  await page.goto(url + '/');
  await page.fill('#token', token);
  await page.click('#connect');
  await page.waitForFunction(() => document.querySelectorAll('#axis option').length > 0);
  await page.selectOption('#axis', axis);
  const info = await page.textContent('#axis-info');
  log('axis:', info);
  check(/EtherCAT/.test(info), 'the bus kind shown');
  check(/SubDevice \d+/.test(info), 'the SubDevice shown');
  check(/cycle 4000 Hz/.test(info), 'the cycle rate shown');

  await page.waitForFunction(() => !document.getElementById('start').disabled, null, { timeout: 30000 });
  await page.selectOption('#excitation', 'multisine');
  await page.fill('#band-lo', '1');
  await page.fill('#band-hi', '500');
  await page.fill('#amplitude', '0.5');
  await page.fill('#periods', '4');
  await page.fill('#duration', '10');
  await page.click('#start');
  await page.waitForFunction(() => document.getElementById('outcome').dataset.outcome === 'completed',
    null, { timeout: 120000 });
  await page.waitForFunction(() => document.querySelectorAll('#params tbody tr').length > 0);
  const rows = await page.$$eval('#params tbody tr', (trs) => trs.map((tr) => [...tr.cells].map((c) => c.textContent)));
  for (const r of rows) log('param:', r.join(' | '));
  const value = (name) => Number((rows.find((r) => r[0].startsWith(name)) || [])[1]);
  const names = ['J1', 'J2', 'J3', 'c1', 'c2'];
  for (const p of names) check(Number.isFinite(value(p)) && value(p) > 0, `${p} is a positive number`);
  check(rows.every((r) => r[3].length > 0), 'units shown');
  check(await page.$eval('#bode', (s) => s.dataset.model) === '1', 'model drawn over the measurement');
  console.log('browser: result ' + names.map((p) => `${p}=${value(p)}`).join(' '));
  await page.screenshot({ path: shot, fullPage: true });
  log('screenshot', shot);
});

// What every browser script of tests/daemon_web.rs shares: the environment it is given,
// one `browser: ...` line per observation, checks that stop the script, and headless
// chromium launched without network beyond loopback, a page whose script errors (and,
// when asked, failed HTTP responses) fail the run.
import { chromium } from 'playwright-core';

/** FLEXID_URL, FLEXID_TOKEN and FLEXID_SCREENSHOT; exits 2 when one is missing. */
export function daemonEnv() {
  const url = process.env.FLEXID_URL;
  const token = process.env.FLEXID_TOKEN;
  const shot = process.env.FLEXID_SCREENSHOT;
  if (!url || !token || !shot) {
    console.error('FLEXID_URL, FLEXID_TOKEN and FLEXID_SCREENSHOT are required');
    process.exit(2);
  }
  return { url, token, shot };
}

export const log = (...a) => console.log('browser:', ...a);

export function check(cond, msg) {
  if (!cond) throw new Error('check failed: ' + msg);
}

/**
 * Runs `body(page, errors)` on a fresh page of headless chromium. `errors` collects the
 * page's script errors (and HTTP responses >= 400 with `httpErrors`); the body may clear
 * it after an error it provoked. Ends with `ok` when the body passed and no error is left,
 * exits 1 with the cause otherwise.
 */
export async function runPage({ width, height, httpErrors = false }, body) {
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    // no network beyond loopback here: keep chromium from calling home
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking',
      '--disable-dev-shm-usage', '--disable-quic', '--no-first-run', '--disable-component-update',
      '--disable-sync'],
  });
  const errors = [];
  try {
    const page = await browser.newPage({ viewport: { width, height } });
    page.on('pageerror', (e) => errors.push(String(e)));
    page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    if (httpErrors) {
      page.on('response', (r) => { if (r.status() >= 400) errors.push(`${r.status()} ${r.request().method()} ${r.url()}`); });
    }
    await body(page, errors);
    check(errors.length === 0, 'no script errors: ' + errors.join('; '));
    log('ok');
  } catch (e) {
    console.error('browser: FAILED:', e.message);
    if (errors.length) console.error('browser: page errors:', errors.join('; '));
    await browser.close();
    process.exit(1);
  }
  await browser.close();
}

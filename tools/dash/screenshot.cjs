// Screenshot of the torque-dash page once the edge clock has reached T_S seconds (the README figure):
//   NODE_PATH=tools/dash/node_modules node tools/dash/screenshot.cjs http://127.0.0.1:8080/ docs/img/dashboard.png 9.6
// Debian's Chromium, headless, through playwright-core (no browser download).
'use strict';
const {chromium} = require('playwright-core');
const [url, out, tArg] = process.argv.slice(2);
(async () => {
  const browser = await chromium.launch({executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
           '--disable-sync', '--no-first-run', '--disable-quic']});
  const page = await browser.newPage({viewport: {width: 1400, height: 1000}});
  await page.goto(url);
  await page.waitForFunction(t => Number.parseFloat(document.getElementById('last-t').textContent) >= t,
                             Number(tArg || 0), {timeout: 120000, polling: 50});
  await new Promise(r => setTimeout(r, 250));  // the next redraw
  await page.screenshot({path: out, fullPage: true});
  console.log(`${out} at t = ${await page.textContent('#last-t')} s`);
  await browser.close();
})().catch(e => { console.error(e); process.exit(1); });

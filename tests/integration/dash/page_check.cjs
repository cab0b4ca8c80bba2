// Drives the torque-dash page in Debian's headless Chromium (playwright-core, no browser download) during a
// paced replay and asserts that live values appear and update.
// Usage: node page_check.cjs URL SCREENSHOT.png [HOLD_S] [READY_FILE] (HOLD_S: keep the page open and live that
// much longer before the screenshot, as a user watching it would; READY_FILE: written once the page has loaded,
// so the test starts the replay only then: under load Chromium can take longer to start than the replay lasts).
// Exit 0 = pass; prints one line per check.
'use strict';
const {chromium} = require('playwright-core');

const [url, shot, holdArg, readyFile] = process.argv.slice(2);
const holdS = Number(holdArg || 0);
const fail = msg => { console.error(`FAIL: ${msg}`); process.exitCode = 1; };
const sleep = ms => new Promise(r => setTimeout(r, ms));

async function readValues(page) {
  return page.evaluate(() => {
    const num = id => Number.parseFloat(document.getElementById(id).textContent);
    const chart = id => Chart.getChart(id);
    return {
      t: num('last-t'), rpm: num('rpm'), fused: num('fused'), cycle: num('cycle'), samples: num('samples'),
      conn: document.getElementById('conn').textContent, health: document.getElementById('health').textContent,
      engineOptions: document.getElementById('engine').options.length,
      speedPoints: chart('c-speed').data.datasets[0].data.length,
      torquePoints: chart('c-torque').data.datasets.map(d => d.data.length),
      incycleSets: chart('c-incycle').data.datasets.length,
      incyclePoints: chart('c-incycle').data.datasets.reduce((n, d) => n + d.data.length, 0),
      incycleAngles: chart('c-incycle').data.datasets.flatMap(d => d.data.map(p => p.x)),
      incycleLabels: chart('c-incycle').data.datasets.map(d => d.label),
      tdc: (chart('c-incycle').$tdc || []).length,
      bars: chart('c-cyl').data.datasets[0].data.length,
      statusRows: document.querySelectorAll('#status-table tr').length,
      fuelCells: document.querySelectorAll('#cells-table td').length,
      fuelRefs: document.getElementById('fuel-refs').textContent,
    };
  });
}

(async () => {
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
           '--disable-sync', '--no-first-run', '--disable-quic'],
  });
  try {
    const page = await browser.newPage({viewport: {width: 1400, height: 1050}});
    const errors = [];
    page.on('pageerror', e => errors.push(String(e)));
    page.on('console', m => { if (m.type() === 'error') errors.push(m.text()); });
    await page.goto(url);
    // Before the replay starts: connected, but no sample yet -> "waiting for data" and its banner, not "live".
    await page.waitForFunction(() => document.getElementById('conn').textContent === 'waiting for data' &&
                                     !document.getElementById('waiting').hidden, null, {timeout: 20000})
      .then(() => console.log('before data: badge "waiting for data", banner shown'),
            () => fail('before data: no "waiting for data" badge and banner within 20 s'));
    if (readyFile) require('fs').writeFileSync(readyFile, 'loaded\n');
    // Live values appear: a crank speed and a fused torque within 20 s.
    await page.waitForFunction(() => Number.parseFloat(document.getElementById('fused').textContent) === 
                                     Number.parseFloat(document.getElementById('fused').textContent) &&
                                     Number.parseFloat(document.getElementById('rpm').textContent) > 0,
                               null, {timeout: 60000});
    const a = await readValues(page);
    await sleep(2500);
    const b = await readValues(page);
    console.log(`first: t=${a.t} s rpm=${a.rpm} fused=${a.fused} cycle=${a.cycle} samples=${a.samples}`);
    console.log(`later: t=${b.t} s rpm=${b.rpm} fused=${b.fused} cycle=${b.cycle} samples=${b.samples}`);
    console.log(`charts: speed ${b.speedPoints} pts, torque ${b.torquePoints}, in-cycle ${b.incycleSets} sets ` +
                `${b.incyclePoints} pts, TDC marks ${b.tdc}, cylinder bars ${b.bars}, status rows ${b.statusRows}`);
    if (b.conn !== 'live') fail(`connection badge "${b.conn}"`);
    if (!(await page.evaluate(() => document.getElementById('waiting').hidden))) fail('"waiting for data" still shown');
    if (!(b.t > a.t + 1.0)) fail(`edge-clock time did not advance by > 1 s in 2.5 s of a paced replay (${a.t} -> ${b.t})`);
    if (!(b.cycle > a.cycle)) fail(`cycle counter did not advance (${a.cycle} -> ${b.cycle})`);
    if (!(b.samples > a.samples)) fail('no new samples');
    if (!(b.rpm > 300 && b.rpm < 8000)) fail(`crank speed ${b.rpm} rpm outside the demo's range`);
    if (!(Math.abs(b.fused) < 1000)) fail(`fused torque ${b.fused} N m not plausible`);
    if (b.engineOptions !== 1) fail(`engine selector has ${b.engineOptions} entries, expected 1`);
    if (!(b.speedPoints > 20)) fail('speed chart nearly empty');
    if (!b.torquePoints.every(n => n > 5)) fail(`torque chart series ${b.torquePoints}`);
    if (!(b.incycleSets >= 2 && b.incyclePoints > 40)) fail('in-cycle chart nearly empty');
    if (!b.incycleAngles.every(x => x >= 0 && x < 720)) fail('in-cycle angles outside [0, 720)');
    // Legend labels are the registry's (idl/methods.hpp, sent in the snapshot), not method ids.
    if (!b.incycleLabels.every(l => /^(Kalman|Fourier) /.test(l))) fail(`in-cycle labels ${b.incycleLabels}`);
    if (b.tdc !== 4) fail(`expected 4 TDC marks (4 cylinders), got ${b.tdc}`);
    // The fuel model's learned speed x MAP cells: a 4 x 4 grid and its reference count.
    if (b.fuelCells !== 16 || !/^\d+/.test(b.fuelRefs)) fail(`fuel model cells ${b.fuelCells}, references "${b.fuelRefs}"`);
    if (b.bars !== 4) fail(`expected 4 cylinder bars, got ${b.bars}`);
    if (!['OK', 'DEGRADED'].includes(b.health)) fail(`daemon health "${b.health}"`);
    if (b.statusRows < 3) fail('status table empty');
    if (errors.length) fail(`page errors: ${errors.join(' | ')}`);
    if (holdS > 0) {
      await sleep(holdS * 1000);
      const c = await readValues(page);
      console.log(`after ${holdS} s more: t=${c.t} s rpm=${c.rpm} fused=${c.fused} cycle=${c.cycle} samples=${c.samples}`);
      if (!(c.samples > b.samples)) fail('the page stopped updating');
    }
    await page.screenshot({path: shot, fullPage: true});
    console.log(`screenshot: ${shot}`);
  } finally {
    await browser.close();
  }
  if (!process.exitCode) console.log('dashboard page: all checks passed');
})().catch(e => { console.error(`FAIL: ${e.stack || e}`); process.exit(1); });

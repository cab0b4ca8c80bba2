// torque-dash page: one WebSocket (/ws) brings a snapshot then deltas of every engine; the selected engine is
// drawn with Chart.js (Debian's libjs-chart.js). Bounded: a fixed number of points per series is kept.
'use strict';
const KEEP_POINTS = 5000;     // per time series
const WINDOW_S = 20;          // time charts show the last 20 s of the edge clock
const INCYCLE_CYCLES = 3;     // in-cycle chart: the latest complete cycles (+ the running one)
const HEALTH = ['valid', 'not converged', 'not excited', 'stale input', 'invalid input', 'no sync', 'numerical',
                'disabled'];
const HEALTH_COLOR = ['', '#ffe08280', '#ffd0a080', '#c8c8c880', '#ff8a8080', '#d1b3ff80', '#ff80c080',
                      '#e0e0e080'];
// The method registry (idl/methods.hpp) as the server sends it in its snapshot: labels, and which methods are
// in-cycle (drawn on the crank angle). Styles go by position among the in-cycle methods (1st solid red, ...).
let methods = [];
const INCYCLE_STYLE = [
  {rgb: '198,40,40', dash: []}, {rgb: '30,136,229', dash: [5, 3]}, {rgb: '67,160,71', dash: [2, 2]},
  {rgb: '142,36,170', dash: [8, 2, 2, 2]}
];
const methodLabel = id => (methods.find(m => m.id === id) || {label: String(id)}).label;

const engines = new Map();  // id -> state
let selected = null;
let geometry = {cylinders: 0, tdc_deg: []};
let samples = 0;

function engineState(id) {
  if (!engines.has(id)) {
    engines.set(id, {seg: [], cyc: [], incycle: [], cylinder: null, status: null, crank: null, unplaced: 0});
    const sel = document.getElementById('engine');
    const o = document.createElement('option');
    o.value = id; o.textContent = `engine ${id}`;
    sel.appendChild(o);
    if (selected === null) { selected = id; sel.value = id; }
  }
  return engines.get(id);
}
function pushBounded(a, items, keep) { a.push(...items); if (a.length > keep) a.splice(0, a.length - keep); }

// Engines the server expired (silent for its engine expiry): off the list and the charts; the selection moves to
// the first engine left.
function expire(ids) {
  const sel = document.getElementById('engine');
  for (const id of ids) {
    engines.delete(id);
    for (const o of [...sel.options]) if (Number(o.value) === id) o.remove();
  }
  if (selected !== null && !engines.has(selected)) {
    selected = engines.size > 0 ? engines.keys().next().value : null;
    if (selected !== null) sel.value = selected;
  }
}

function ingest(msg) {
  if (msg.expired) expire(msg.expired);
  if (msg.geometry) geometry = msg.geometry;
  if (msg.methods) methods = msg.methods;
  for (const [key, e] of Object.entries(msg.engines)) {
    const st = engineState(Number(key));
    const seg = [], cyc = [];
    for (const r of e.torque) {
      const p = {t: r[0], kind: r[1], cyl: r[2], cycle: r[3], rpm: r[4], brake: r[5], ind: r[6], fused: r[7],
                 q: r[8], validity: r[9]};
      (p.kind === 1 ? cyc : seg).push(p);
    }
    pushBounded(st.seg, seg, KEEP_POINTS);
    pushBounded(st.cyc, cyc, KEEP_POINTS);
    pushBounded(st.incycle, e.incycle.map(r => ({t: r[0], cycle: r[1], deg: r[2], method: r[3], v: r[4],
                                                 health: r[5]})), 4000);
    if (e.cylinder) st.cylinder = e.cylinder;
    if (e.status) st.status = e.status;
    if (e.crank) st.crank = e.crank;
    st.unplaced = e.unplaced;
    st.outOfRange = e.out_of_range || 0;
    samples += e.torque.length + e.incycle.length;
  }
}

// Shades the x spans in which the fused estimate was not valid, coloured by the health reason.
const qualityShade = {
  id: 'qualityShade',
  beforeDatasetsDraw(chart) {
    const spans = chart.$spans || [];
    const {ctx, chartArea: a, scales: {x}} = chart;
    ctx.save();
    for (const s of spans) {
      const x0 = Math.max(a.left, x.getPixelForValue(s.t0)), x1 = Math.min(a.right, x.getPixelForValue(s.t1));
      if (x1 <= x0) continue;
      ctx.fillStyle = HEALTH_COLOR[s.q] || '#ff000040';
      ctx.fillRect(x0, a.top, x1 - x0, a.bottom - a.top);
    }
    ctx.restore();
  }
};
// Vertical TDC marks on the in-cycle chart.
const tdcMarks = {
  id: 'tdcMarks',
  afterDatasetsDraw(chart) {
    if (!chart.$tdc) return;
    const {ctx, chartArea: a, scales: {x}} = chart;
    ctx.save();
    ctx.strokeStyle = '#555'; ctx.setLineDash([4, 4]); ctx.fillStyle = '#333'; ctx.font = '11px sans-serif';
    for (const m of chart.$tdc) {
      const px = x.getPixelForValue(m.deg);
      ctx.beginPath(); ctx.moveTo(px, a.top); ctx.lineTo(px, a.bottom); ctx.stroke();
      ctx.fillText(`TDC ${m.cylinder}`, px + 3, a.top + 11);
    }
    ctx.restore();
  }
};
// Imbalance and misfire labels above the per-cylinder bars.
const barLabels = {
  id: 'barLabels',
  afterDatasetsDraw(chart) {
    const c = chart.$cyl;
    if (!c) return;
    const {ctx} = chart;
    const meta = chart.getDatasetMeta(0);
    ctx.save(); ctx.font = '12px sans-serif'; ctx.textAlign = 'center';
    meta.data.forEach((bar, i) => {
      const mis = recentMisfire(c, i);
      ctx.fillStyle = mis ? '#c62828' : '#333';
      const imb = c.imbalance_pct[i];
      ctx.fillText(`${imb === null ? '–' : (imb >= 0 ? '+' : '') + imb.toFixed(1)} %`, bar.x, bar.y - 6);
      if (mis) ctx.fillText('MISFIRE', bar.x, bar.y - 20);
      const n = c.misfires[i];
      if (n) { ctx.fillStyle = mis ? '#fff' : '#c62828'; ctx.fillText(`${n} misfire${n > 1 ? 's' : ''}`, bar.x, chart.chartArea.bottom - 8); }
    });
    ctx.restore();
  }
};

function lineChart(id, datasets, xTitle, yTitle, plugins = [], xOpts = {}) {
  return new Chart(document.getElementById(id), {
    type: 'line',
    data: {datasets},
    options: {
      animation: false, parsing: false, normalized: true, maintainAspectRatio: false, spanGaps: false,
      elements: {point: {radius: 0}, line: {borderWidth: 1.5}},
      scales: {x: Object.assign({type: 'linear', title: {display: true, text: xTitle}}, xOpts),
               y: {title: {display: true, text: yTitle}}},
      plugins: {legend: {labels: {boxWidth: 12}}, tooltip: {enabled: false}},
    },
    plugins,
  });
}

const charts = {
  speed: lineChart('c-speed', [{label: 'crank speed', borderColor: '#1565c0', data: []}], 't [s]', 'rpm'),
  torque: lineChart('c-torque', [
    {label: 'fused', borderColor: '#000', data: [], borderWidth: 2, borderDash: [6, 3]},
    {label: 'brake', borderColor: '#1e88e5', data: []},
    {label: 'indicated', borderColor: '#e53935', data: []},
  ], 't [s]', 'N m', [qualityShade]),
  incycle: lineChart('c-incycle', [], 'crank angle after tooth 0 [deg]', 'indicated torque [N m]', [tdcMarks],
                     {min: 0, max: 720, ticks: {stepSize: 90}}),
  cyl: new Chart(document.getElementById('c-cyl'), {
    type: 'bar',
    data: {labels: [], datasets: [{label: 'indicated torque per cylinder [N m]', data: [], backgroundColor: []}]},
    options: {animation: false, maintainAspectRatio: false, layout: {padding: {top: 30}},
              plugins: {legend: {display: false}}, scales: {y: {title: {display: true, text: 'N m'}}}},
    plugins: [barLabels],
  }),
};

function qualitySpans(cyc) {
  const spans = [];
  for (let i = 0; i < cyc.length; ++i) {
    const p = cyc[i];
    if (p.q === 0) continue;
    const t0 = i > 0 ? cyc[i - 1].t : p.t;
    const last = spans[spans.length - 1];
    if (last && last.q === p.q && last.t1 === t0) last.t1 = p.t; else spans.push({t0, t1: p.t, q: p.q});
  }
  return spans;
}

function setText(id, v) { document.getElementById(id).textContent = v; }
const fmt = (v, d = 1) => (v === null || v === undefined || !isFinite(v)) ? '–' : v.toFixed(d);

function drawTimeCharts(st) {
  const tEnd = Math.max(st.seg.length ? st.seg[st.seg.length - 1].t : 0, st.cyc.length ? st.cyc[st.cyc.length - 1].t : 0);
  const t0 = Math.min(st.seg.length ? st.seg[0].t : tEnd, st.cyc.length ? st.cyc[0].t : tEnd);
  const tMin = Math.max(tEnd - WINDOW_S, t0);
  const seg = st.seg.filter(p => p.t >= tMin), cyc = st.cyc.filter(p => p.t >= tMin);
  charts.speed.data.datasets[0].data = seg.map(p => ({x: p.t, y: p.rpm}));
  const ds = charts.torque.data.datasets;
  ds[0].data = cyc.map(p => ({x: p.t, y: p.fused}));
  ds[1].data = cyc.map(p => ({x: p.t, y: p.brake}));
  ds[2].data = cyc.map(p => ({x: p.t, y: p.ind}));
  charts.torque.$spans = qualitySpans(cyc);
  for (const c of [charts.speed, charts.torque]) {
    c.options.scales.x.min = tMin; c.options.scales.x.max = tEnd; c.update('none');
  }
  const used = new Set(charts.torque.$spans.map(s => s.q));
  document.getElementById('quality-legend').innerHTML = [...used].sort().map(
    q => `<span><i style="background:${HEALTH_COLOR[q]}"></i>${HEALTH[q] || 'health ' + q}</span>`).join('');
}

function drawInCycle(st) {
  const byCycle = new Map();
  for (const p of st.incycle) {
    const k = `${p.cycle}:${p.method}`;
    if (!byCycle.has(k)) byCycle.set(k, {cycle: p.cycle, method: p.method, pts: []});
    byCycle.get(k).pts.push({x: p.deg, y: p.v});
  }
  const cycles = [...new Set(st.incycle.map(p => p.cycle))].sort((a, b) => a - b).slice(-(INCYCLE_CYCLES + 1));
  const newest = cycles[cycles.length - 1];
  const sets = [];
  for (const g of byCycle.values()) {
    if (!cycles.includes(g.cycle)) continue;
    const age = newest - g.cycle;  // 0 = running cycle
    const alpha = [1, 0.7, 0.45, 0.25][Math.min(age, 3)];
    const k = Math.max(0, methods.filter(m => m.in_cycle).findIndex(m => m.id === g.method));
    const style = INCYCLE_STYLE[k % INCYCLE_STYLE.length];
    sets.push({
      label: `${methodLabel(g.method)} ${age === 0 ? 'now' : '−' + age}`,
      data: g.pts,
      borderColor: `rgba(${style.rgb},${alpha})`,
      borderDash: style.dash,
      order: age
    });
  }
  sets.sort((a, b) => a.label.localeCompare(b.label));
  charts.incycle.data.datasets = sets;
  charts.incycle.$tdc = geometry.tdc_deg;
  charts.incycle.update('none');
}

// A misfire lasts one cycle: its cylinder stays red for MISFIRE_HOLD_S of the edge clock.
const MISFIRE_HOLD_S = 2.0;
function recentMisfire(c, i) {
  return ((c.misfire_mask >> i) & 1) || (c.last_misfire_t_s[i] >= 0 && c.t_s - c.last_misfire_t_s[i] < MISFIRE_HOLD_S);
}

function drawCylinders(st) {
  const c = st.cylinder;
  if (!c) return;
  const n = c.indicated.length;
  charts.cyl.data.labels = Array.from({length: n}, (_, i) => `cyl ${i + 1}`);
  charts.cyl.data.datasets[0].data = c.indicated;
  charts.cyl.data.datasets[0].backgroundColor = c.indicated.map((_, i) => recentMisfire(c, i) ? '#c62828' : '#43a047');
  charts.cyl.$cyl = c;
  charts.cyl.update('none');
}

function drawStatus(st) {
  const s = st.status;
  if (!s) return;
  const h = document.getElementById('health');
  h.textContent = s.health;
  h.className = 'badge ' + (s.health === 'OK' ? 'ok' : s.health === 'DEGRADED' ? 'warn' : 'bad');
  document.getElementById('flags').innerHTML = s.flags.map(f => `<span class="flag">${f}</span>`).join('');
  const rows = [
    ['uptime', `${fmt(s.uptime_s)} s`], ['edges', s.edges], ['teeth', s.teeth], ['CAN frames', s.can_frames],
    ['cycles', s.cycles], ['sync losses', s.sync_losses],
    ['ring drops edge / CAN / out', `${s.ring_drops_edge} / ${s.ring_drops_can} / ${s.ring_drops_out}`],
    ['source drops', s.source_drops], ['overruns', s.overruns],
    ['latency p50 / p99 / max', `${s.latency_us.map(v => fmt(v, 0)).join(' / ')} µs`],
    ['stale CAN signals (mask)', s.sensor_timeouts],
    ['burn phase (in-cycle model)',
     `${['not used', 'learning', 'converged', 'imported'][s.burn_phase_state] ?? s.burn_phase_state}, ${fmt(s.burn_phase_offset_deg, 1)}°`],
  ];
  let html = '';
  for (let i = 0; i < rows.length; i += 3)
    html += '<tr>' + rows.slice(i, i + 3).map(r => `<td>${r[0]}</td><td><b>${r[1]}</b></td>`).join('') + '</tr>';
  document.querySelector('#status-table tbody').innerHTML = html;
  drawCells(s);
}

// The fuel model's learned speed x MAP cells (DaemonStatus.fuel_cells, bit 4*s+m) and its reference count: which
// operating points the fused brake torque rests on a learned model, which on its prior.
const SPEED_BANDS = ['< 1500', '1500-2500', '2500-3500', '>= 3500'], MAP_BANDS = ['< 40', '40-60', '60-80', '>= 80'];
function drawCells(s) {
  setText('fuel-refs', s.fuel_references === 0 ? '0 (prior only)' : s.fuel_references);
  let html = '<tr><th>MAP (kPa) / speed (rpm)</th>' + SPEED_BANDS.map(b => `<th>${b}</th>`).join('') + '</tr>';
  for (let m = MAP_BANDS.length - 1; m >= 0; --m) {
    html += `<tr><th>${MAP_BANDS[m]}</th>`;
    for (let sp = 0; sp < SPEED_BANDS.length; ++sp) {
      const learned = (s.fuel_cells >> (4 * sp + m)) & 1;
      html += `<td class="${learned ? 'cell-on' : 'cell-off'}">${learned ? 'learned' : 'prior'}</td>`;
    }
    html += '</tr>';
  }
  document.querySelector('#cells-table tbody').innerHTML = html;
}

function draw() {
  setText('samples', samples);
  const st = engines.get(selected);
  if (!st) return;
  const lastSeg = st.seg[st.seg.length - 1], lastCyc = st.cyc[st.cyc.length - 1];
  setText('rpm', fmt(st.crank ? st.crank.rpm : lastSeg && lastSeg.rpm, 0));
  if (lastCyc) {
    setText('fused', fmt(lastCyc.fused)); setText('brake', fmt(lastCyc.brake)); setText('indicated', fmt(lastCyc.ind));
    setText('quality', HEALTH[lastCyc.q] || lastCyc.q); setText('cycle', lastCyc.cycle);
  }
  const tLast = Math.max(lastSeg ? lastSeg.t : 0, lastCyc ? lastCyc.t : 0);
  setText('last-t', fmt(tLast, 3));
  setText('unplaced', st.unplaced);
  setText('out-of-range', st.outOfRange);  // a foreign or corrupt writer's absurd values: counted, red
  document.getElementById('out-of-range').className = st.outOfRange > 0 ? 'badge bad' : 'badge ok';
  drawTimeCharts(st); drawInCycle(st); drawCylinders(st); drawStatus(st);
}

let dirty = false;
function scheduleDraw() {
  if (dirty) return;
  dirty = true;
  setTimeout(() => { dirty = false; draw(); }, 200);  // at most 5 redraws per second whatever the data rate
}

// "live" only once a sample arrived: until then the badge and a banner say the page waits for data (a page
// with empty charts and a green badge would look like a daemon estimating nothing).
let seenData = false;
function showConnected(conn) {
  conn.textContent = seenData ? 'live' : 'waiting for data';
  conn.className = seenData ? 'badge ok' : 'badge warn';
  document.getElementById('waiting').hidden = seenData;
}

function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  const conn = document.getElementById('conn');
  ws.onopen = () => showConnected(conn);
  ws.onclose = () => { conn.textContent = 'disconnected: retrying'; conn.className = 'badge bad';
                       setTimeout(connect, 1000); };
  ws.onmessage = ev => {
    ingest(JSON.parse(ev.data));
    if (!seenData && samples > 0) { seenData = true; showConnected(conn); }
    scheduleDraw();
  };
}

document.getElementById('engine').addEventListener('change', ev => { selected = Number(ev.target.value); draw(); });
document.getElementById('fox-url').textContent = `ws://${location.host}/`;
window.dashState = {engines, get samples() { return samples; }, get selected() { return selected; }};
connect();

// Shared by the Foxglove and MCAP checks: the daemon's CSV recording (torqued --record DIR) and a comparison
// of JSON samples (Foxglove messages, MCAP messages) with its rows, matched by (topic, kind, seq).
'use strict';
const fs = require('fs');
const path = require('path');

function readCsv(file) {
  const lines = fs.readFileSync(file, 'utf8').split('\n').filter(l => l.length);
  const cols = lines[0].split(',');
  return lines.slice(1).map(l => {
    const f = l.split(','), row = {};
    cols.forEach((c, i) => { row[c] = f[i]; });
    return row;
  });
}

// CSV files of the recording per topic, as in idl/sample_recorder.hpp.
const FILES = {
  EngineTorque: ['engine_cycle.csv', 'engine_segment.csv'], EstimatorTorque: ['estimator_torque.csv'],
  CylinderTorque: ['cylinder_torque.csv'], DaemonStatus: ['daemon_status.csv'],
};
// Fields compared per topic (CSV: doubles at 6 decimals, so 1e-6 tolerance; integers exactly).
const FIELDS = {
  EngineTorque: ['engine_id', 'cycle', 'cylinder', 'speed_rad_s', 'brake_nm', 'indicated_nm', 'friction_nm', 'fused_nm',
                 'quality', 'validity', 'source_t_ns'],
  EstimatorTorque: ['engine_id', 'method', 'value_nm', 'uncertainty', 'health', 'source_t_ns'],
  CylinderTorque: ['engine_id', 'cycle', 'cylinders', 'misfire_mask', 'health', 'source_t_ns'],
  DaemonStatus: ['engine_id', 'health', 'edges', 'teeth', 'cycles', 'ring_drops_out'],
};
// EngineTorque: seq per writer, segments and cycles in separate files; EstimatorTorque: seq per method (instance).
const key = (topic, o) =>
  `${topic}:${topic === 'EngineTorque' ? o.kind : topic === 'EstimatorTorque' ? o.method : ''}:${o.seq}`;
const csvColumn = f => (f === 'source_t_ns' ? 't_ns' : f);  // the CSV's first column is the source time

function loadRecording(dir) {
  const rows = new Map(), counts = {};
  for (const [topic, files] of Object.entries(FILES)) {
    counts[topic] = 0;
    for (const f of files) {
      const p = path.join(dir, f);
      if (!fs.existsSync(p)) continue;
      for (const r of readCsv(p)) { rows.set(key(topic, r), r); ++counts[topic]; }
    }
  }
  return {rows, counts};
}

/// Compares samples {topic, ...fields} with the recording; returns a list of problems (empty = equal).
function compare(samples, rec, label) {
  const problems = [];
  let matched = 0;
  for (const s of samples) {
    if (!FIELDS[s.topic]) continue;
    const r = rec.rows.get(key(s.topic, s));
    if (!r) { problems.push(`${label}: ${s.topic} seq ${s.seq} not in the CSV recording`); continue; }
    const fields = [...FIELDS[s.topic]];
    if (s.topic === 'CylinderTorque')  // arrays: CSV columns name_1..name_8
      for (const arr of ['indicated_nm', 'imbalance_pct'])
        s[arr].forEach((v, i) => { s[`${arr}_${i + 1}`] = v; fields.push(`${arr}_${i + 1}`); });
    for (const f of fields) {
      const a = Number(s[f] === null ? NaN : s[f]), b = Number(r[csvColumn(f)]);
      const ok = (Number.isNaN(a) && (Number.isNaN(b) || r[csvColumn(f)] === 'nan')) || Math.abs(a - b) <= 1.01e-6;
      if (!ok) problems.push(`${label}: ${s.topic} seq ${s.seq} ${f}: ${s[f]} vs CSV ${r[csvColumn(f)]}`);
    }
    ++matched;
  }
  return {problems: problems.slice(0, 20), problemCount: problems.length, matched};
}

/// Checks a JSON sample against the JSON Schema of its channel (types, integer bounds, array sizes, required).
function checkSchema(obj, schema) {
  for (const req of schema.required) if (!(req in obj)) return `missing field ${req}`;
  for (const [k, v] of Object.entries(obj)) {
    const p = schema.properties[k];
    if (!p) return `field ${k} not in the schema`;
    const types = [].concat(p.type);
    const t = v === null ? 'null' : Array.isArray(v) ? 'array' : Number.isInteger(v) && types.includes('integer') ? 'integer'
      : typeof v === 'number' ? 'number' : typeof v;
    if (!types.includes(t)) return `field ${k}: ${t} where the schema says ${types}`;
    if (t === 'integer' && (v < p.minimum || v > p.maximum)) return `field ${k}: ${v} outside [${p.minimum}, ${p.maximum}]`;
    if (t === 'array' && v.length !== p.minItems) return `field ${k}: ${v.length} items, schema ${p.minItems}`;
    if ('const' in p && v !== p.const) return `field ${k}: ${v} != ${p.const}`;
  }
  return '';
}

/// torque-dash's summary line: {topic: {received, gaps}} (samples it took from DDS, and seq gaps it saw).
function parseDashSummary(text) {
  const out = {};
  for (const m of text.matchAll(/(\w+) (\d+) \(seq gaps (\d+)\)/g)) out[m[1]] = {received: Number(m[2]), gaps: Number(m[3])};
  return out;
}

/// Per reliable topic: `got` (messages seen by the checker) equals what torque-dash took from DDS, and what
/// torque-dash took plus the seq gaps it counted equals the daemon's recording (every sample is accounted for:
/// a subscriber starved of CPU loses its own samples, the daemon never waits for it). Returns problems.
function accountFor(got, dash, rec, label) {
  const problems = [];
  for (const t of ['EngineTorque', 'CylinderTorque', 'EstimatorTorque']) {
    const d = dash[t];
    if (!d) { problems.push(`${label}: no torque-dash summary for ${t}`); continue; }
    if (got[t] !== d.received) problems.push(`${t}: ${label} has ${got[t]}, torque-dash took ${d.received} from DDS`);
    if (d.received + d.gaps !== rec.counts[t])
      problems.push(`${t}: torque-dash took ${d.received} + ${d.gaps} seq gaps != ${rec.counts[t]} recorded by the daemon`);
    if (!(d.received >= 0.5 * rec.counts[t])) problems.push(`${t}: torque-dash took only ${d.received} of ${rec.counts[t]}`);
  }
  return problems;
}

module.exports = {readCsv, loadRecording, compare, checkSchema, parseDashSummary, accountFor};

// Subscribes to every channel of torque-dash's Foxglove WebSocket server with the protocol's published client
// (@foxglove/ws-protocol over the ws package), during a paced replay, until the daemon reports the end of the
// replay and torque-dash has exited; then checks every message against its channel's JSON Schema, against the
// daemon's CSV recording (equal values) and against torque-dash's own count of what it took from DDS (nothing
// lost between DDS and the Foxglove client; every recorded sample accounted for).
// Usage: node foxglove_check.cjs WS_URL READY_FILE RECORDING_DIR DONE_FILE DASH_LOG. Exit 0 = pass.
'use strict';
const fs = require('fs');
const WebSocket = require('ws');
const {FoxgloveClient} = require('@foxglove/ws-protocol');
const {loadRecording, compare, checkSchema, parseDashSummary, accountFor} = require('./compare.cjs');

const [url, readyFile, recDir, doneFile, dashLog] = process.argv.slice(2);
const fail = msg => { console.error(`FAIL: ${msg}`); process.exitCode = 1; };
const TOPICS = ['EngineTorque', 'EstimatorTorque', 'CylinderTorque', 'CrankState', 'DaemonStatus'];
const STATUS_REPLAY_DONE = 64;

const client = new FoxgloveClient({ws: new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL])});
const subs = new Map();  // subscription id -> channel
const samples = [];
let serverInfo = null, schemaErrors = [], done = false;
const decoder = new TextDecoder();

const timer = setTimeout(() => finish('time-out: no end-of-replay status within 90 s'), 90000);
client.on('serverInfo', m => { serverInfo = m; });
client.on('error', e => fail(`client error: ${e}`));
client.on('advertise', channels => {
  for (const ch of channels) {
    if (ch.encoding !== 'json' || ch.schemaEncoding !== 'jsonschema') fail(`channel ${ch.topic}: ${ch.encoding}/${ch.schemaEncoding}`);
    ch.parsedSchema = JSON.parse(ch.schema);
    subs.set(client.subscribe(ch.id), ch);
  }
  const topics = [...subs.values()].map(c => c.topic).sort();
  console.log(`advertised and subscribed: ${topics.join(' ')}`);
  if (topics.length !== 5 || !TOPICS.every(t => topics.some(x => x.endsWith('/' + t)))) fail(`channels ${topics}`);
  setTimeout(() => fs.writeFileSync(readyFile, 'subscribed\n'), 300);  // the subscribe message is on its way
});
client.on('message', ({subscriptionId, data}) => {
  const ch = subs.get(subscriptionId);
  if (!ch) { fail(`message for unknown subscription ${subscriptionId}`); return; }
  const obj = JSON.parse(decoder.decode(data));
  const err = checkSchema(obj, ch.parsedSchema);
  if (err && schemaErrors.length < 10) schemaErrors.push(`${ch.topic}: ${err}`);
  if (!ch.topic.endsWith('/' + obj.topic)) fail(`${obj.topic} on channel ${ch.topic}`);
  samples.push(obj);
  if (obj.topic === 'DaemonStatus' && (obj.flags & STATUS_REPLAY_DONE)) replayDone = true;
});
let replayDone = false, closed = false;
client.on('close', () => { closed = true; });
// The test script creates doneFile once the daemon and torque-dash (--until-done) have exited; the connection
// closes after torque-dash sent its last queued message.
(function poll(n) {
  if (fs.existsSync(doneFile) && (closed || n < -50)) return finish(replayDone ? '' : 'no end-of-replay status');
  setTimeout(() => poll(n - 1), 100);
})(0);

function finish(why) {
  if (done) return;
  done = true;
  clearTimeout(timer);
  check(why);
}

function check(why) {
  if (why) fail(why);
  if (!serverInfo || serverInfo.name !== 'torque-dash') fail('no serverInfo from torque-dash');
  if (schemaErrors.length) fail(`schema violations: ${schemaErrors.join(' | ')}`);
  const per = {};
  for (const s of samples) per[s.topic] = (per[s.topic] || 0) + 1;
  console.log(`received: ${JSON.stringify(per)}`);
  const eng = samples.filter(s => s.topic === 'EngineTorque' && s.kind === 1).map(s => s.seq);
  if (eng.length) console.log(`EngineTorque cycles: seq ${eng[0]}..${eng[eng.length - 1]} (${eng.length})`);
  const rec = loadRecording(recDir);
  console.log(`daemon CSV recording: ${JSON.stringify(rec.counts)}`);
  const cmp = compare(samples, rec, 'foxglove');
  // Subscribed before the daemon started: every sample torque-dash took arrived here, with the recorded values.
  const dash = parseDashSummary(fs.readFileSync(dashLog, 'utf8'));
  console.log(`torque-dash took from DDS: ${JSON.stringify(dash)}`);
  for (const p of accountFor(per, dash, rec, 'the Foxglove client')) fail(p);
  if (!(rec.counts.EngineTorque > 1000)) fail(`too few EngineTorque rows recorded (${rec.counts.EngineTorque})`);
  if (!(per.CrankState > 100)) fail(`too few CrankState messages (${per.CrankState})`);
  if (cmp.problemCount) fail(`${cmp.problemCount} mismatches: ${cmp.problems.join(' | ')}`);
  console.log(`compared with the CSV recording: ${cmp.matched} samples equal`);
  if (!process.exitCode) console.log('foxglove: all checks passed');
  setTimeout(() => process.exit(process.exitCode || 0), 100);
}

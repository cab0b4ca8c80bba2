// Reads torque-dash's MCAP recording with the MCAP reference reader (@mcap/core; zstd chunks through fzstd):
// McapStreamReader (record structure, magic, footer, chunk CRCs) and McapIndexedReader (summary CRC, chunk and
// message indexes); compares the messages with the daemon's CSV recording.
// Usage: node mcap_check.cjs FILE.mcap RECORDING_DIR DASH_LOG. Exit 0 = pass.
'use strict';
const fs = require('fs');
const {McapStreamReader, McapIndexedReader} = require('@mcap/core');
const fzstd = require('fzstd');
const {loadRecording, compare, checkSchema, parseDashSummary, accountFor} = require('./compare.cjs');
const decompressHandlers = {zstd: (buf, size) => fzstd.decompress(buf, new Uint8Array(Number(size)))};

const [file, recDir, dashLog] = process.argv.slice(2);
const fail = msg => { console.error(`FAIL: ${msg}`); process.exitCode = 1; };

const bytes = new Uint8Array(fs.readFileSync(file));
const reader = new McapStreamReader({validateCrcs: true, decompressHandlers, includeChunks: true});
reader.append(bytes);
const schemas = new Map(), channels = new Map(), types = {}, samples = [];
let stats = null, schemaErrors = [], lastLogTime = 0n, order = 0;
const decoder = new TextDecoder();
for (let rec; (rec = reader.nextRecord());) {
  types[rec.type] = (types[rec.type] || 0) + 1;
  if (rec.type === 'Schema') schemas.set(rec.id, {...rec, parsed: JSON.parse(decoder.decode(rec.data))});
  else if (rec.type === 'Channel') channels.set(rec.id, rec);
  else if (rec.type === 'Statistics') stats = rec;
  else if (rec.type === 'Message') {
    const ch = channels.get(rec.channelId);
    if (!ch) { fail(`message on unknown channel ${rec.channelId}`); continue; }
    const obj = JSON.parse(decoder.decode(rec.data));
    const err = checkSchema(obj, schemas.get(ch.schemaId).parsed);
    if (err && schemaErrors.length < 10) schemaErrors.push(`${ch.topic}: ${err}`);
    if (rec.logTime < lastLogTime) ++order;
    lastLogTime = rec.logTime;
    samples.push(obj);
  }
}
if (!reader.done()) fail('the reader did not reach the closing magic (truncated file?)');
console.log(`records: ${JSON.stringify(types)}`);
if (schemas.size !== 5 || channels.size !== 5) fail(`${schemas.size} schemas, ${channels.size} channels`);
for (const ch of channels.values())
  if (ch.messageEncoding !== 'json' || schemas.get(ch.schemaId).encoding !== 'jsonschema') fail(`channel ${ch.topic} encoding`);
if (!stats || Number(stats.messageCount) !== samples.length) fail(`statistics ${stats && stats.messageCount} vs ${samples.length} messages`);
if (order) fail(`${order} messages with log_time going back`);
if (schemaErrors.length) fail(`schema violations: ${schemaErrors.join(' | ')}`);
const per = {};
for (const s of samples) per[s.topic] = (per[s.topic] || 0) + 1;
console.log(`messages: ${JSON.stringify(per)}`);
const rec = loadRecording(recDir);
console.log(`daemon CSV recording: ${JSON.stringify(rec.counts)}`);
const dash = parseDashSummary(fs.readFileSync(dashLog, 'utf8'));
console.log(`torque-dash took from DDS: ${JSON.stringify(dash)}`);
for (const p of accountFor(per, dash, rec, 'the MCAP file')) fail(p);
if (!(rec.counts.EngineTorque > 1000)) fail(`too few EngineTorque rows (${rec.counts.EngineTorque})`);
const cmp = compare(samples, rec, 'mcap');
if (cmp.problemCount) fail(`${cmp.problemCount} mismatches: ${cmp.problems.join(' | ')}`);
console.log(`compared with the CSV recording: ${cmp.matched} samples equal`);

// The indexed reader: every message through the chunk indexes and message indexes, the summary CRC checked.
(async () => {
  const readable = {size: async () => BigInt(bytes.length),
                    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length))};
  const ix = await McapIndexedReader.Initialize({readable, decompressHandlers});
  let n = 0;
  for await (const m of ix.readMessages({validateCrcs: true})) if (m.channelId) ++n;
  const written = Number((fs.readFileSync(dashLog, 'utf8').match(/MCAP messages (\d+)/) || [])[1]);
  console.log(`indexed reader: ${n} messages in ${ix.chunkIndexes.length} chunks ` +
              `(${[...new Set(ix.chunkIndexes.map(c => c.compression))]}); torque-dash wrote ${written}`);
  if (n !== samples.length || n !== written) fail(`indexed reader ${n}, streamed ${samples.length}, written ${written}`);
  if (!ix.chunkIndexes.length || ix.chunkIndexes.some(c => c.compression !== 'zstd')) fail('chunks not zstd');
  if (!process.exitCode) console.log('mcap: all checks passed');
})().catch(e => fail(`indexed reader: ${e.message || e}`));

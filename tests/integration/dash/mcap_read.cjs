// Reads an MCAP file with the MCAP reference reader (@mcap/core), zstd chunks through fzstd, both ways:
//   indexed: McapIndexedReader (footer, summary, chunk indexes, message indexes; CRCs validated);
//   stream:  McapStreamReader (record by record from the start, chunk CRCs validated), which also reads a file
//            cut short (kill -9) up to its last complete record.
// Prints one JSON object: {indexed: {...} | {error}, stream: {...}}. Used by mcap_check.cjs, the writer's unit test
// (tests/tools/test_mcap_writer.cpp) and the kill -9 test (tests/integration/mcap_kill_test.sh).
// Usage: node mcap_read.cjs FILE.mcap
'use strict';
const fs = require('fs');
const {McapIndexedReader, McapStreamReader} = require('@mcap/core');
const fzstd = require('fzstd');

const decompressHandlers = {zstd: (buf, size) => fzstd.decompress(buf, new Uint8Array(Number(size)))};

function tally(into, msg) {
  into.messages += 1;
  into.perChannel[msg.channelId] = (into.perChannel[msg.channelId] || 0) + 1;
  const t = msg.logTime;
  if (into.firstLogTime === null || t < BigInt(into.firstLogTime)) into.firstLogTime = t.toString();
  if (into.lastLogTime === null || t > BigInt(into.lastLogTime)) into.lastLogTime = t.toString();
  const last = into.lastSeq[msg.channelId];
  if (last !== undefined && msg.sequence !== last + 1) into.seqGaps += 1;
  into.lastSeq[msg.channelId] = msg.sequence;
}
const empty = () => ({messages: 0, perChannel: {}, firstLogTime: null, lastLogTime: null, lastSeq: {}, seqGaps: 0});

async function indexed(fd, size) {
  const readable = {
    size: async () => BigInt(size),
    read: async (offset, length) => {
      const b = Buffer.alloc(Number(length));
      fs.readSync(fd, b, 0, Number(length), Number(offset));
      return new Uint8Array(b.buffer, b.byteOffset, b.length);
    },
  };
  const r = await McapIndexedReader.Initialize({readable, decompressHandlers});
  const out = empty();
  out.chunks = r.chunkIndexes.length;
  out.compression = [...new Set(r.chunkIndexes.map(c => c.compression))];
  out.statistics = r.statistics ? Number(r.statistics.messageCount) : null;
  out.channels = r.channelsById.size;
  out.schemas = r.schemasById.size;
  for await (const m of r.readMessages({validateCrcs: true})) tally(out, m);
  return out;
}

function stream(bytes) {
  const r = new McapStreamReader({validateCrcs: true, decompressHandlers, includeChunks: true});
  r.append(bytes);
  const out = empty();
  out.records = {};
  try {
    for (let rec; (rec = r.nextRecord());) {
      out.records[rec.type] = (out.records[rec.type] || 0) + 1;
      if (rec.type === 'Message') tally(out, rec);
    }
  } catch (e) {
    out.error = String(e.message || e);
  }
  out.done = r.done();
  return out;
}

(async () => {
  const file = process.argv[2];
  const bytes = new Uint8Array(fs.readFileSync(file));
  const fd = fs.openSync(file, 'r');
  let ix;
  try {
    ix = await indexed(fd, bytes.length);
  } catch (e) {
    ix = {error: String(e.message || e)};
  }
  console.log(JSON.stringify({indexed: ix, stream: stream(bytes)}));
})();

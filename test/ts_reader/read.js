// Reads an MCAP file as Foxglove and Lichtblick do (@mcap/core): through its summary and
// indexes, every message in log-time order; then once more as a stream, record by record.
// Prints one JSON object: what it read (see test/ts_reader.py).
"use strict";
const fs = require("fs");
const crypto = require("crypto");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const fzstd = require("fzstd");

const decompressHandlers = {
  zstd: (data, size) => fzstd.decompress(data, new Uint8Array(Number(size))),
};

class FileReadable {
  constructor(buf) { this.buf = buf; }
  async size() { return BigInt(this.buf.length); }
  async read(offset, length) {
    return new Uint8Array(this.buf.buffer, this.buf.byteOffset + Number(offset), Number(length));
  }
}

async function main(path) {
  const buf = fs.readFileSync(path);
  const reader = await McapIndexedReader.Initialize({
    readable: new FileReadable(buf), decompressHandlers,
  });
  const topic = new Map([...reader.channelsById].map(([id, ch]) => [id, ch.topic]));
  const counts = {}, hashes = {};
  let last = -1n, backwards = 0;
  for await (const m of reader.readMessages()) {
    const t = topic.get(m.channelId);
    counts[t] = (counts[t] || 0) + 1;
    if (m.logTime < last) backwards++;
    last = m.logTime;
    (hashes[t] = hashes[t] || crypto.createHash("sha256")).update(m.data);
  }
  const streamed = {};
  let badSequences = 0, streamedTotal = 0;
  const stream = new McapStreamReader({ decompressHandlers });
  stream.append(new Uint8Array(buf));
  for (let r = stream.nextRecord(); r; r = stream.nextRecord()) {
    if (r.type !== "Message") continue;
    streamedTotal++;
    streamed[r.channelId] = (streamed[r.channelId] || 0) + 1;
    if (r.sequence !== streamed[r.channelId]) badSequences++;
  }
  const schemas = [...reader.schemasById.values()].map((s) => s.name);
  const digests = Object.fromEntries(Object.entries(hashes).map(([k, h]) => [k, h.digest("hex")]));
  console.log(JSON.stringify({
    counts, digests, backwards, badSequences, streamedTotal,
    schemas: schemas.sort(), complete: stream.done(),
  }));
}

main(process.argv[2]).catch((e) => { console.error(String(e && e.stack || e)); process.exit(1); });

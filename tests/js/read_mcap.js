// Independent reader of pamd recordings: @mcap/core (TypeScript, from npm) reads the
// file through its summary and indexes (as Foxglove does) and again as a stream, and
// decodes the CDR messages from their ros2msg schema text with its own decoder here.
// Usage: node read_mcap.js FILE  -> one JSON object on stdout.
"use strict";
const fs = require("fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const fzstd = require("fzstd");
const lz4 = require("lz4js");

const decompressHandlers = {
  zstd: (buf) => fzstd.decompress(buf),
  lz4: (buf) => lz4.decompress(buf),
};

const { flatFields, decodeCdrValues: decodeCdr } = require("./cdr");

async function main() {
  const file = process.argv[2];
  const bytes = fs.readFileSync(file);
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  const out = { channels: {}, metadata: {}, attachments: [], messages: {}, stream_counts: {} };
  const fieldsOf = {};
  for (const [id, ch] of reader.channelsById) {
    const schema = reader.schemasById.get(ch.schemaId);
    out.channels[ch.topic] = {
      id, encoding: ch.messageEncoding, schema: schema ? schema.name : "",
      schema_encoding: schema ? schema.encoding : "",
      count: Number(reader.statistics.channelMessageCounts.get(id) ?? 0n),
    };
    out.messages[ch.topic] = [];
    if (ch.messageEncoding === "cdr" && schema && schema.encoding === "ros2msg") {
      const fields = flatFields(new TextDecoder().decode(schema.data));
      fieldsOf[id] = fields;
      out.channels[ch.topic].fields = fields.map((f) => f[0]);
    }
  }
  for await (const m of reader.readMessages()) {
    const topic = reader.channelsById.get(m.channelId).topic;
    const body = fieldsOf[m.channelId]
      ? decodeCdr(fieldsOf[m.channelId], m.data)
      : JSON.parse(new TextDecoder().decode(m.data));
    out.messages[topic].push([m.logTime.toString(), body]);
  }
  for await (const md of reader.readMetadata()) out.metadata[md.name] = Object.fromEntries(md.metadata);
  for await (const a of reader.readAttachments()) {
    out.attachments.push({ name: a.name, media_type: a.mediaType, text: new TextDecoder().decode(a.data) });
  }
  // and once more as a plain stream of records, with CRCs checked
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(bytes);
  const topics = {};
  let rec;
  while ((rec = stream.nextRecord())) {
    if (rec.type === "Channel") topics[rec.id] = rec.topic;
    if (rec.type === "Message") {
      const t = topics[rec.channelId];
      out.stream_counts[t] = (out.stream_counts[t] || 0) + 1;
    }
  }
  out.stream_done = stream.done();
  process.stdout.write(JSON.stringify(out));
}

main().catch((e) => {
  process.stderr.write(`read_mcap.js: ${e.stack || e}\n`);
  process.exit(1);
});

// A Foxglove viewer that is not pamd's code: the protocol's own client library
// (@foxglove/ws-protocol's FoxgloveClient over the `ws` WebSocket) connects to a pamd
// live view, subscribes to the topics asked for and decodes every message with the
// schema the server advertised (ros2msg text -> CDR by alignment; jsonschema -> JSON).
// Usage: node foxglove_view.js ws://HOST:PORT --topics T1,T2 [--count N] [--seconds S]
//        [--timeout S] [--connect-timeout S] [--summary] [--stall-after N]
// Ends after N messages on the first topic, S seconds of receiving, or the timeout;
// prints one JSON object: server info, advertised channels, decoded messages (each
// with its log time in ns and the wall-clock receive time in ns), or with --summary
// only counts and the receive-minus-log-time latency percentiles of each topic.
// --stall-after N: a stalled viewer, that stops reading its socket after N messages
// (and stays connected until the timeout). The first message received is announced
// on stderr ("receiving"), so a test knows the viewer is subscribed.
"use strict";
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const { flatFields, decodeCdrValues } = require("./cdr");

function decodeCdr(fields, data) {
  const values = decodeCdrValues(fields, data);
  const obj = {};
  fields.forEach(([name], i) => { obj[name] = values[i]; });
  return obj;
}

function arg(name, dflt) {
  const i = process.argv.indexOf(name);
  return i > 0 ? process.argv[i + 1] : dflt;
}

function wallNs() {
  return BigInt(Math.round((performance.timeOrigin + performance.now()) * 1e3)) * 1000n;
}

function pct(sorted, p) {
  if (!sorted.length) return null;
  return sorted[Math.min(sorted.length - 1, Math.floor((p / 100) * sorted.length))];
}

const url = process.argv[2];
const topics = (arg("--topics", "") || "").split(",").filter(Boolean);
const count = Number(arg("--count", "0"));
const seconds = Number(arg("--seconds", "0"));
const timeoutS = Number(arg("--timeout", "60"));
const connectS = Number(arg("--connect-timeout", "30"));
const summary = process.argv.includes("--summary");
const stallAfter = Number(arg("--stall-after", "0"));
let received = 0;

const out = { url, server: null, channels: [], messages: {}, counts: {}, last: {},
  latency_ms: {}, errors: [] };
const lat = {};
const decoders = {}; // subscription id -> [topic, decode]
let client = null;
let firstAt = null;
let done = false;

function finish(code) {
  if (done) return;
  done = true;
  for (const [t, xs] of Object.entries(lat)) {
    xs.sort((a, b) => a - b);
    out.latency_ms[t] = { n: xs.length, p50: pct(xs, 50), p99: pct(xs, 99),
      max: xs.length ? xs[xs.length - 1] : null };
  }
  if (summary) delete out.messages;
  process.stdout.write(JSON.stringify(out) + "\n");
  try { client && client.close(); } catch (e) { /* closing anyway */ }
  process.exit(code);
}

function subscribe(channels) {
  for (const ch of channels) {
    out.channels.push({ topic: ch.topic, encoding: ch.encoding, schemaName: ch.schemaName,
      schemaEncoding: ch.schemaEncoding, schema: ch.schema });
    if (!topics.includes(ch.topic)) continue;
    let decode;
    if (ch.encoding === "cdr" && ch.schemaEncoding === "ros2msg") {
      const fields = flatFields(ch.schema);
      decode = (d) => decodeCdr(fields, d);
    } else if (ch.encoding === "json") {
      JSON.parse(ch.schema); // the advertised jsonschema must itself be JSON
      decode = (d) => JSON.parse(Buffer.from(d.buffer, d.byteOffset, d.byteLength).toString());
    } else {
      out.errors.push(`cannot decode ${ch.topic}: ${ch.encoding}/${ch.schemaEncoding}`);
      continue;
    }
    decoders[client.subscribe(ch.id)] = [ch.topic, decode];
    out.messages[ch.topic] = [];
    out.counts[ch.topic] = 0;
    lat[ch.topic] = [];
  }
}

function connect(deadline) {
  // The SDK's server speaks the protocol as "foxglove.sdk.v1" (the same protocol as
  // "foxglove.websocket.v1" under its new name); the client takes what the socket offers.
  const ws = new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  client = new FoxgloveClient({ ws });
  let opened = false;
  client.on("open", () => { opened = true; });
  client.on("error", (e) => {
    if (!opened && Date.now() < deadline) return; // the server is not up yet: retry
    out.errors.push(String(e && e.message ? e.message : e));
  });
  client.on("close", () => {
    if (!opened && Date.now() < deadline) { setTimeout(() => connect(deadline), 200); return; }
    if (!done) { out.errors.push("connection closed by the server"); finish(3); }
  });
  client.on("serverInfo", (info) => { out.server = info; });
  client.on("advertise", subscribe);
  client.on("message", (m) => {
    const recv = wallNs();
    const entry = decoders[m.subscriptionId];
    if (!entry) return;
    const [topic, decode] = entry;
    let body;
    try { body = decode(m.data); } catch (e) { out.errors.push(`${topic}: ${e}`); return; }
    out.counts[topic] += 1;
    out.last[topic] = body;
    lat[topic].push(Number(recv - m.timestamp) / 1e6);
    if (!summary) {
      out.messages[topic].push({ log_ns: m.timestamp.toString(), recv_ns: recv.toString(),
        body });
    }
    received += 1;
    if (stallAfter > 0 && received === stallAfter) ws._socket.pause(); // stop reading
    if (firstAt === null) {
      process.stderr.write("receiving\n");
      firstAt = Date.now();
      if (seconds > 0) setTimeout(() => finish(0), seconds * 1000);
    }
    if (count > 0 && topic === topics[0] && out.counts[topic] >= count) finish(0);
  });
}

connect(Date.now() + connectS * 1000);
setTimeout(() => { out.errors.push(`timed out after ${timeoutS} s`); finish(2); },
  timeoutS * 1000);

// CDR decoding of pamd's flat ros2msg schemas (one primitive per line, by alignment):
// the tests' own decoder, not pamd's, shared by the MCAP reader (read_mcap.js) and the
// Foxglove viewer (foxglove_view.js). NaN comes out as the string "NaN" (JSON has none).
"use strict";

const PRIM = {
  bool: [1, (v, o) => v.getUint8(o) !== 0], byte: [1, (v, o) => v.getUint8(o)],
  char: [1, (v, o) => v.getInt8(o)], int8: [1, (v, o) => v.getInt8(o)],
  uint8: [1, (v, o) => v.getUint8(o)], int16: [2, (v, o) => v.getInt16(o, true)],
  uint16: [2, (v, o) => v.getUint16(o, true)], int32: [4, (v, o) => v.getInt32(o, true)],
  uint32: [4, (v, o) => v.getUint32(o, true)],
  int64: [8, (v, o) => Number(v.getBigInt64(o, true))],
  uint64: [8, (v, o) => Number(v.getBigUint64(o, true))],
  float32: [4, (v, o) => v.getFloat32(o, true)], float64: [8, (v, o) => v.getFloat64(o, true)],
};

function flatFields(text) {
  const out = [];
  for (const raw of text.split("\n")) {
    const line = raw.split("#")[0].trim();
    if (!line) continue;
    const [type, name] = line.split(/\s+/);
    if (!PRIM[type]) throw new Error(`unsupported field type ${type}`);
    out.push([name, type]);
  }
  return out;
}

function decodeCdrValues(fields, data) {
  const v = new DataView(data.buffer, data.byteOffset, data.byteLength);
  if (v.getUint8(0) !== 0 || v.getUint8(1) !== 1) throw new Error("not little-endian CDR");
  let pos = 0; // counted after the 4-byte encapsulation header
  const row = [];
  for (const [, type] of fields) {
    const [size, get] = PRIM[type];
    pos += (size - (pos % size)) % size;
    const x = get(v, 4 + pos);
    row.push(typeof x === "number" && Number.isNaN(x) ? "NaN" : x);
    pos += size;
  }
  if (4 + pos !== data.byteLength) throw new Error(`CDR size ${data.byteLength} != ${4 + pos}`);
  return row;
}

module.exports = { flatFields, decodeCdrValues };

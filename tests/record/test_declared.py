"""A real recorded run against the declarations (pamd.wire.declare): the file's schemas, read
back by the independent `mcap` and `mcap_ros2` readers, hold exactly the field
table's fields and types; every event of the run (in the file and as the loop emitted
it) is a declared kind with its declared payload and passes the file's own event JSON
schema (checked by `jsonschema`); the CSV and MAT exports' columns and units are the
table's."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import jsonschema
from mcap.reader import make_reader
from mcap_ros2._vendor.rosidl_adapter.parser import parse_message_string
from mcap_ros2.decoder import DecoderFactory

from pamd.client.export import export_mat, export_named_csv
from pamd.client.field_info import MUSCLE_COLUMNS
from pamd.wire.declare import events, fields
from pamd.wire.declare.deprecated import FLAG_NAMES

PY_TYPE = {"float64": float, "uint8": int, "uint16": int, "uint32": int, "uint64": int}


def test_a_recorded_run_is_what_the_declarations_say(recorded_run: Any, tmp_path: Path) -> None:
    # a profile: start-up, transitions, its command and verdict, the summary
    run = recorded_run(duration_s=1.0, profile={"kind": "sine", "min_bar": 1.0,
                                                "max_bar": 2.0, "freq_hz": 1.0})
    path = run.files[0]
    schemas: dict[str, tuple[str, bytes]] = {}
    recorded: list[dict[str, Any]] = []
    first: dict[str, Any] = {}
    with open(path, "rb") as fh:
        for schema, ch, msg in make_reader(fh).iter_messages():
            assert schema is not None
            schemas[ch.topic] = (schema.encoding, schema.data)
            if ch.message_encoding == "json":
                recorded.append(json.loads(msg.data))
            elif ch.topic not in first:
                decode = DecoderFactory().decoder_for(ch.message_encoding, schema)
                assert decode is not None
                first[ch.topic] = decode(msg.data)
    enc, text = schemas["/pamd/sim/state/m1"]
    assert enc == "ros2msg"
    spec = parse_message_string("pamd_msgs", "MuscleState", text.decode())
    assert [(f.name, f.type.type) for f in spec.fields] == [
        (f.name, f.type) for f in fields.muscle_message()]
    enc, text = schemas["/pamd/sim/loop"]
    spec = parse_message_string("pamd_msgs", "LoopTiming", text.decode())
    assert [(f.name, f.type.type) for f in spec.fields] == [(f.name, f.type) for f in fields.LOOP]
    for topic, table in (("/pamd/sim/state/m1", fields.muscle_message()),
                         ("/pamd/sim/loop", fields.LOOP)):
        msg = first[topic]
        assert list(msg.__slots__) == [f.name for f in table]
        for f in table:
            assert type(getattr(msg, f.name)) is PY_TYPE[f.type], (topic, f.name)

    # events: the file's own schema, and the registry
    enc, text = schemas["/pamd/sim/events"]
    assert enc == "jsonschema"
    schema = json.loads(text)
    assert schema["properties"]["kind"]["enum"] == [k.name for k in events.DECLARED
                                                    if k.recorded]
    assert {e["kind"] for e in recorded} >= {"transition", "command", "startup"}
    for e in recorded:
        jsonschema.validate(e, schema)
        assert events.problems(e["kind"], e["data"]) == [], e
    emitted = run.cap.events
    assert {k for _, k, _ in emitted} >= {"transition", "command", "startup"}
    for _, kind, data in emitted:
        assert events.problems(kind, json.loads(json.dumps(data, default=str))) == [], (
            kind, data)

    # exports: the columns and units of the table
    out = export_named_csv(path, str(tmp_path / "csv"))
    with open(out["m1"][0], newline="") as fh:
        header = next(csv.reader(fh))
    derived = [f.name for f in fields.DERIVED]
    assert header == [*MUSCLE_COLUMNS, *derived]
    with open(out["loop"][0], newline="") as fh:
        assert next(csv.reader(fh))[:len(fields.LOOP)] == list(fields.LOOP_NAMES)
    side = json.loads(Path(out["sidecar"][0]).read_text())
    for name, doc in side["columns"].items():
        f = fields.BY_NAME[name]
        assert (doc["unit"], doc["description"]) == (f.unit, f.description)
    assert set(side["columns"]) >= set(fields.MUSCLE_NAMES) | set(derived)
    assert {n: d["meaning"] for n, d in side["flags"].items() if n not in FLAG_NAMES} == {
        f.name: m for f, m in fields.FLAG_MEANINGS.items()}
    for old, new in FLAG_NAMES.items():  # a deprecated flag name beside its new one
        assert side["flags"][old]["bit"] == side["flags"][new]["bit"]

    from scipy.io import loadmat
    mat = str(tmp_path / "run.mat")
    export_mat(path, mat)
    m1 = loadmat(mat, simplify_cells=True)["m1"]
    assert [c for c in m1 if c in fields.BY_NAME] == [*MUSCLE_COLUMNS, *derived]
    assert {k: m1["units"][k] for k in MUSCLE_COLUMNS} == {
        k: fields.BY_NAME[k].unit for k in MUSCLE_COLUMNS}
    assert all(m1["flag_bits"][old] == m1["flag_bits"][new] for old, new in FLAG_NAMES.items())

"""The recorder's files for experiment steps, read back with the `mcap` reader and its
ROS 2 decoder: a collection announced to a recorder that is already writing a run file
(`pamd.wire.record.control`) gets one file per step in its own directory, from the tick its
first step begins to the tick the plan ends, and the run goes on in a new ordinary
file; a plan of `pamd collect` (steps known at the start) keeps the rest of the run in
its last step's file; every tick lands in exactly one file."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from pamd.iohost.io_spec import IoSpec
from pamd.iohost.recorder import Recorder
from pamd.wire.record import control
from pamd.wire.record.record_spec import RecordSpec
from pamd.wire.ring import BlockLayout
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS

I_SEG = LOOP_FIELDS.index("segment")
STEPS = ({"step": "light", "index": 0, "plan": "quick", "load_kg": 15.0},
         {"step": "heavy", "index": 1, "plan": "quick", "load_kg": 50.0})


def recorder(run_dir: Path, steps: tuple[dict[str, Any], ...] = ()) -> Recorder:
    n = len(LOOP_FIELDS) + len(MUSCLE_FIELDS)
    rs = RecordSpec(dir=str(run_dir), run_name="run", rotate_mb=None, rotate_s=None,
                    chunk_kb=64, flush_s=1.0, compression="zstd",
                    started_at="20250101-000000", metadata={"pamd": {"run_name": "run"}},
                    steps=steps)
    spec = IoSpec(shm_name="", layout=BlockLayout(record_bytes=8 * n, tick_slots=64),
                  rig_id="sim", muscles=("m1",), rate_hz=100.0, virtual=True,
                  wall0_ns=time.time_ns(), clock0_s=0.0, parent_pid=os.getpid(), record=rs)
    rec = Recorder(spec)
    rec.t_start = 0.0
    rec.open()
    return rec


def feed(rec: Recorder, first: int, segments: list[int]) -> int:
    """One tick per entry of `segments` (its `segment` field), from tick `first`."""
    n = len(LOOP_FIELDS) + len(MUSCLE_FIELDS)
    for k, seg in enumerate(segments):
        row = [0.0] * n
        row[0], row[1], row[I_SEG] = float(first + k), (first + k) / 100.0, float(seg)
        rec.tick(tuple(row))
    return first + len(segments)


def read(path: str) -> dict[str, Any]:
    """Ticks (tick, segment) of the loop topic, events and metadata of one file."""
    out: dict[str, Any] = {"ticks": [], "events": []}
    with open(path, "rb") as fh:
        r = make_reader(fh, decoder_factories=[DecoderFactory()])
        decoders: dict[int, Any] = {}  # one ROS 2 decoder per schema, not per message
        for schema, ch, m in r.iter_messages():
            if ch.topic == "/pamd/sim/loop":
                if schema.id not in decoders:
                    decoders[schema.id] = DecoderFactory().decoder_for(ch.message_encoding,
                                                                       schema)
                msg = decoders[schema.id](m.data)
                out["ticks"].append((msg.tick, msg.segment))
            elif ch.topic == "/pamd/sim/events":
                out["events"].append(json.loads(m.data))
        out["meta"] = {x.name: dict(x.metadata) for x in r.iter_metadata()}
    return out


def test_a_collection_switches_into_its_directory_and_back(tmp_path: Path) -> None:
    run_dir, coll_dir = tmp_path / "rec", tmp_path / "rec" / "quick-20250101-000100"
    rec = recorder(run_dir)
    t = feed(rec, 0, [0] * 10)
    rec.control(json.loads(control.begin_message(
        7, str(coll_dir), "quick", "20250101-000100", STEPS,
        {"pamd": {"run_name": "quick"}, "pamd.collection": {"dir": str(coll_dir)}})))
    t = feed(rec, t, [0] * 5 + [1] * 10 + [2] * 10 + [0] * 5)
    rec.finish(None, "test")
    assert [n["what"] for n in rec.notices] == ["begun", "closed"]
    assert rec.notices[1] == {"what": "closed", "id": 7, "dir": str(coll_dir), "ticks": 20,
                              "files": 2}
    run0, light, heavy, run1 = rec.files
    assert os.path.basename(light) == "20250101-000100_sim_quick_01-light.mcap"
    assert os.path.basename(heavy) == "20250101-000100_sim_quick_02-heavy.mcap"
    assert os.path.dirname(light) == os.path.dirname(heavy) == str(coll_dir)
    assert os.path.dirname(run1) == str(run_dir) and run1 != run0
    assert os.path.basename(run1).endswith("_sim_run.mcap")
    files = {p: read(p) for p in rec.files}
    # every tick in exactly one file, each step's from its first tick to its last
    assert files[run0]["ticks"] == [(k, 0) for k in range(15)]
    assert files[light]["ticks"] == [(k, 1) for k in range(15, 25)]
    assert files[heavy]["ticks"] == [(k, 2) for k in range(25, 35)]
    assert files[run1]["ticks"] == [(k, 0) for k in range(35, 40)]
    for path, step in ((light, STEPS[0]), (heavy, STEPS[1])):
        meta = files[path]["meta"]
        assert meta["pamd.experiment"] == {k: str(v) for k, v in step.items()}
        assert meta["pamd"]["run_name"] == "quick"
        assert meta["pamd.collection"] == {"dir": str(coll_dir)}
    for path in (run0, run1):
        meta = files[path]["meta"]
        assert "pamd.experiment" not in meta and "pamd.collection" not in meta
        assert meta["pamd"]["run_name"] == "run"
    # the run's files say where the collection went and what it wrote
    [begun] = [e for e in files[run0]["events"] if e["kind"] == "collection"]
    assert begun["data"]["what"] == "begun" and begun["tick"] == 15
    [closed] = [e for e in files[run1]["events"] if e["kind"] == "collection"]
    assert closed["data"]["files"] == [os.path.basename(light), os.path.basename(heavy)]


def test_a_collection_ended_before_its_first_step_is_dropped(tmp_path: Path) -> None:
    rec = recorder(tmp_path / "rec")
    t = feed(rec, 0, [0] * 5)
    rec.control(json.loads(control.begin_message(
        3, str(tmp_path / "rec" / "c"), "quick", "20250101-000100", STEPS, {})))
    rec.control(json.loads(control.end_message(4)))  # another collection's: not this one
    assert rec.pending is not None and rec.notices == []
    rec.control(json.loads(control.end_message(3)))  # the loop refused it
    assert rec.notices == [{"what": "dropped", "id": 3, "dir": str(tmp_path / "rec" / "c")}]
    feed(rec, t, [1] * 5 + [0] * 5)  # a plan nobody announced: no files of its own
    rec.finish(None, "test")
    assert len(rec.files) == 1 and not (tmp_path / "rec" / "c").exists()
    assert read(rec.files[0])["ticks"] == [(k, 1 if 5 <= k < 10 else 0) for k in range(15)]


def test_steps_known_at_the_start_keep_the_rest_in_the_last_step_file(tmp_path: Path) -> None:
    rec = recorder(tmp_path / "out", STEPS)  # pamd collect
    feed(rec, 0, [0] * 3 + [1] * 4 + [2] * 4 + [0] * 3)
    rec.finish(None, "test")
    pre, light, heavy = rec.files
    assert read(pre)["ticks"] == [(k, 0) for k in range(3)]
    assert read(light)["ticks"] == [(k, 1) for k in range(3, 7)]  # its first tick too
    assert read(heavy)["ticks"] == [(7, 2), (8, 2), (9, 2), (10, 2), (11, 0), (12, 0),
                                    (13, 0)]
    assert rec.notices == []

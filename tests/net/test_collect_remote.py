"""`collect` over Zenoh to a running, recording daemon (`pamd run`, virtual clock so no
record is ever lost, telemetry on its own loopback port) gives what `pamd collect`
gives: a collection directory under the recording directory with one MCAP file per
step (same names, same `pamd.experiment` metadata) and a manifest, written when the
plan ends (done, failed by a fault, or cut short by a stop), with a resume into the
same collection; around it, the daemon's recording goes on in ordinary run files.
Every file is read back with the `mcap` reader and its ROS 2 decoder."""

from __future__ import annotations

import glob
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from .conftest import RigProc, pamd_cli, wait_until

RIG = "sim"
PLAN = """name: quick
muscle: m1
settle: {seconds: 1}
profile: {kind: sine, min_bar: 0.0, max_bar: 3.0, freq_hz: 0.5, cycles: CYCLES}
steps:
  - {name: light, load_kg: 15}
  - name: heavy
    load_kg: 50
    SETTLE
"""
GOOD = PLAN.replace("CYCLES", "1").replace("    SETTLE\n", "")
# A stillness that cannot be held long enough: 5 s still wanted within 0.5 s, so the
# second step's settling times out and faults whatever the sensors read (an encoder at
# rest reads exactly 0 mm/s between its 0.01 mm steps: "faster than 1e-6 mm/s" was
# no fault at all now and then).
BAD = PLAN.replace("CYCLES", "1").replace(
    "SETTLE", "settle: {seconds: 0.1, until_still: true, still_for_s: 5, timeout_s: 0.5}")
LONG = PLAN.replace("CYCLES", "500").replace("    SETTLE\n", "")


class Rig(RigProc):
    """The daemon on the virtual clock at 1000 Hz (a settling that never reaches its
    stillness faults there, as in tests/cli/test_collect_cli.py)."""

    def __init__(self, tmp: Path) -> None:
        super().__init__(tmp, RIG, ("--duration", "36000"),
                         loop={"clock": "virtual", "rate_hz": 1000},
                         telemetry={"enabled": True, "plans_dir": "plans"})

    def plan(self, text: str, name: str = "plan.yaml") -> str:
        """The plan written into the daemon's plans_dir; its name (what a request names)."""
        (self.tmp / "plans").mkdir(exist_ok=True)
        (self.tmp / "plans" / name).write_text(text)
        return name

    def collect(self, plan_file: str, start_step: int = 0) -> dict[str, Any]:
        return self.cmd("collect", {"plan_file": plan_file, "start_step": start_step})


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    r = Rig(tmp_path_factory.mktemp("collect"))
    yield r
    r.close()


def manifest_after(directory: str, runs: int, timeout_s: float = 120.0) -> dict[str, Any]:
    """The manifest once it records `runs` runs (it is written when a plan ends)."""

    def read() -> dict[str, Any] | None:
        with open(os.path.join(directory, "manifest.json")) as fh:
            m = json.load(fh)
        return m if len(m["runs"]) >= runs else None

    return wait_until(read, timeout_s, f"{runs} run(s) in the manifest of {directory}")


def read(path: str) -> dict[str, Any]:
    """A file's ticks as (tick, segment), its events and its metadata."""
    out: dict[str, Any] = {"ticks": [], "events": []}
    with open(path, "rb") as fh:
        r = make_reader(fh, decoder_factories=[DecoderFactory()])
        decoders: dict[int, Any] = {}  # one ROS 2 decoder per schema, not per message
        # only the two topics read here go through the reader's log-time ordering
        for schema, ch, m in r.iter_messages(topics=[f"/pamd/{RIG}/loop",
                                                     f"/pamd/{RIG}/events"]):
            if ch.topic == f"/pamd/{RIG}/loop":
                if schema.id not in decoders:
                    decoders[schema.id] = DecoderFactory().decoder_for(ch.message_encoding,
                                                                       schema)
                msg = decoders[schema.id](m.data)
                out["ticks"].append((msg.tick, msg.segment))
            elif ch.topic == f"/pamd/{RIG}/events":
                out["events"].append(json.loads(m.data))
        out["meta"] = {x.name: dict(x.metadata) for x in r.iter_metadata()}
    return out


def check_step_file(path: str, step: str, index: int, load: str) -> dict[str, Any]:
    f = read(path)
    exp = f["meta"]["pamd.experiment"]
    assert exp["step"] == step and exp["index"] == str(index) and exp["plan"] == "quick"
    assert exp["load_kg"].startswith(load)
    assert f["meta"]["pamd"]["run_name"] == "quick"
    assert os.path.basename(path).endswith(f"_{RIG}_quick_{index + 1:02d}-{step}.mcap")
    assert len(f["ticks"]) > 1000  # seconds of 500 Hz ticks: this step's, and only its
    assert {seg for _t, seg in f["ticks"]} == {index + 1}
    ticks = [t for t, _s in f["ticks"]]
    assert ticks == list(range(ticks[0], ticks[0] + len(ticks)))  # none lost in between
    return f


def test_collect_writes_a_file_per_step_and_a_manifest(rig: Rig) -> None:
    files0 = set(glob.glob(str(rig.rec / "*.mcap")))
    assert len(files0) == 1  # the daemon's run file
    v = rig.collect(rig.plan(GOOD))
    assert v["ok"] and v["plan"] == "quick" and v["steps"] == 2, v
    coll = v["collection"]
    assert os.path.dirname(coll) == str(rig.rec) and os.path.basename(coll).startswith(
        "quick-") and v["manifest"] == os.path.join(coll, "manifest.json")
    assert v["resumed"] is False
    m = manifest_after(coll, 1)
    assert [(s["name"], s["status"]) for s in m["steps"]] == [("light", "done"),
                                                              ("heavy", "done")]
    [run] = m["runs"]
    assert run["outcome"] == "done" and run["start_step"] == 0 and run["faults"] == []
    assert run["requested_by"] == f"zenoh:{rig.zid}" and run["user"] == "tester"
    assert run["lost_records"] == 0
    assert m["plan"]["name"] == "quick" and m["plan"]["text"] == GOOD
    light = check_step_file(os.path.join(coll, m["steps"][0]["files"][0]), "light", 0, "15")
    heavy = check_step_file(os.path.join(coll, m["steps"][1]["files"][0]), "heavy", 1, "50")
    assert sorted(run["files"]) == sorted(m["steps"][0]["files"] + m["steps"][1]["files"])
    assert heavy["ticks"][0][0] == light["ticks"][-1][0] + 1  # the steps meet
    assert run["ticks"] == len(light["ticks"]) + len(heavy["ticks"])
    # the daemon records on in a new run file of its own directory
    wait_until(lambda: len(set(glob.glob(str(rig.rec / "*.mcap"))) - files0) == 1, 30,
               "a new run file")
    st = rig.status()
    assert st["experiment"]["outcome"] == "done" and st["experiment"]["collection"] is None
    assert any(os.path.dirname(f) == str(rig.rec) and f not in files0
               for f in st["recording"]["files"])


def test_a_fault_keeps_its_files_and_resume_continues_the_collection(rig: Rig) -> None:
    plan = rig.plan(BAD)
    v = rig.collect(plan)
    assert v["ok"], v
    coll = v["collection"]
    m = manifest_after(coll, 1)
    assert [s["status"] for s in m["steps"]] == ["done", "failed"]
    assert m["runs"][0]["outcome"].startswith("fault") and m["runs"][0]["faults"]
    assert all(len(s["files"]) == 1 for s in m["steps"])  # the failed step's file is kept
    wait_until(lambda: rig.status()["state"] == "FAULT", 30, "FAULT")
    dirs = set(os.listdir(rig.rec))
    v = rig.collect(plan)  # the loop refuses it: no directory is left behind
    assert not v["ok"] and "FAULT" in v["error"] and "collection" not in v, v
    assert set(os.listdir(rig.rec)) == dirs
    assert rig.cmd("reset")["ok"]
    rig.plan(GOOD)  # the operator fixes the plan, then resumes it from the CLI
    r = pamd_cli("cmd", "--connect", rig.endpoint, "collect", "--plan-file", plan,
                 "--start-step", "1")
    assert r.returncode == 0, r.stdout + r.stderr
    v = json.loads(r.stdout)
    assert v["collection"] == coll and v["resumed"] is True and v["start_step"] == 1
    m = manifest_after(coll, 2)
    assert [s["status"] for s in m["steps"]] == ["done", "done"]
    assert [run["start_step"] for run in m["runs"]] == [0, 1]
    assert len(m["steps"][0]["files"]) == 1
    assert len(m["steps"][1]["files"]) == 2  # the failed attempt's and the resumed one's
    assert m["runs"][1]["files"] == [f for f in m["steps"][1]["files"]
                                     if f not in m["runs"][0]["files"]]
    for name in m["steps"][1]["files"]:
        check_step_file(os.path.join(coll, name), "heavy", 1, "50")


def test_collect_refusals_leave_nothing_behind(rig: Rig) -> None:
    dirs = set(os.listdir(rig.rec))
    v = rig.collect(rig.plan(GOOD.replace("name: quick", "name: other"), "other.yaml"), 1)
    assert not v["ok"] and "no unfinished collection of plan 'other'" in v["error"], v
    v = rig.collect(rig.plan(GOOD.replace("load_kg: 50", "load_kg: 500"), "heavy.yaml"))
    assert not v["ok"] and "plan refused" in v["error"], v
    assert set(os.listdir(rig.rec)) == dirs


def test_a_stop_mid_collection_writes_the_manifest_and_every_tick_is_in_one_file(
        rig: Rig) -> None:
    v = rig.collect(rig.plan(LONG))
    assert v["ok"], v
    coll = v["collection"]

    def running() -> dict[str, Any] | None:
        e = rig.status().get("experiment") or {}
        return e if e.get("phase") == "profile" and e.get("collection") else None

    assert wait_until(running, 60, "the profile")["collection"]["collection"] == coll
    assert rig.daemon.stop() == 0, rig.daemon.log()[-3000:]
    m = manifest_after(coll, 1, timeout_s=1.0)  # written by the time the daemon exits
    [run] = m["runs"]
    assert run["outcome"].startswith("aborted") and run["files"], run
    assert [s["status"] for s in m["steps"]] == ["interrupted", "pending"]
    assert len(m["steps"][0]["files"]) == 1
    check_step_file(os.path.join(coll, m["steps"][0]["files"][0]), "light", 0, "15")
    # every tick of the run is in exactly one file: run files (segment 0) and steps
    summary = rig.daemon.summary()
    assert summary["lost_records"] == 0
    files = sorted(glob.glob(str(rig.rec / "*.mcap")) + glob.glob(str(rig.rec / "*/*.mcap")))
    spans = []
    for path in files:
        ticks = read(path)["ticks"]
        segs = {s for _t, s in ticks}
        in_run_dir = os.path.dirname(path) == str(rig.rec)
        assert segs == {0} if in_run_dir else len(segs) == 1 and 0 not in segs, path
        spans.append((ticks[0][0], ticks[-1][0], len(ticks)))
    spans.sort()
    assert spans[0][0] == 0 and sum(n for _a, _b, n in spans) == summary["ticks"]
    for (_a0, b0, _n0), (a1, _b1, _n1) in zip(spans, spans[1:], strict=False):
        assert a1 == b0 + 1  # each file takes up where the one before ended


def test_a_daemon_that_does_not_record_refuses_a_collect(tmp_path: Path) -> None:
    r = RigProc(tmp_path, RIG, ("--no-record",), loop={"clock": "virtual"},
                telemetry={"enabled": True, "plans_dir": "."})
    try:
        v = r.cmd("collect", {"plan_file": "plan.yaml"})
        assert not v["ok"] and "plan refused" in v["error"]  # the plan is read first
        (tmp_path / "plan.yaml").write_text(GOOD)
        v = r.cmd("collect", {"plan_file": "plan.yaml"})
        assert not v["ok"] and "does not record" in v["error"] and "--record" in v["error"]
        assert r.status()["experiment"] is None  # nothing reached the loop
        assert not r.rec.exists()
    finally:
        r.close()

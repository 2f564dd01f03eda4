"""A collection started over the network, the daemon's main-thread side
(`pamd.daemon.host.collections`), with real plans, directories and manifests and a stand-in
for the daemon: where a collection goes (new, or the newest unfinished one of the plan
to resume), what is refused and what a refusal leaves behind (nothing), what the io
process is told, and the manifest a daemon that stops mid-plan writes as it closes.
The whole path over Zenoh is tests/net/test_collect_remote.py."""

from __future__ import annotations

import json
import os
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import yaml

from pamd.config import load_config
from pamd.daemon.host.collections import Collections
from pamd.loop.experiment.manifest import Manifest
from pamd.loop.experiment.plan import load_plan
from pamd.loop.safety.supervisor import Supervisor
from pamd.wire.errors import CommandRefused

PLAN = yaml.safe_dump({
    "name": "quick", "muscle": "m1", "settle": {"seconds": 1},
    "profile": {"kind": "sine", "min_bar": 0.0, "max_bar": 3.0, "freq_hz": 0.5, "cycles": 1},
    "steps": [{"name": "light", "load_kg": 15}, {"name": "heavy", "load_kg": 50}]})


class Setup:
    def __init__(self, tmp: Path, record: bool = True) -> None:
        self.cfg = load_config()
        self.sent: list[dict[str, Any]] = []
        self.events: list[dict[str, Any]] = []
        self.rec = tmp / "rec"
        self.plan_file = tmp / "plan.yaml"
        self.plan_file.write_text(PLAN)
        self.d = SimpleNamespace(
            cfg=self.cfg, io=None, note="", loop=SimpleNamespace(lost_records=0),
            ctrl=SimpleNamespace(tick_no=100, now=1.0, plan_run=None,
                                 supervisor=Supervisor()),
            summary=SimpleNamespace(event=lambda t, kind, data: self.events.append(data)))
        self.c = Collections(self.d, str(self.rec) if record else None, self.send)

    def send(self, blob: bytes) -> bool:
        self.sent.append(json.loads(blob))
        return True

    def prepare(self, start: int = 0, text: str = PLAN, name: str | None = None) -> Any:
        self.plan_file.write_text(text)
        plan = load_plan(str(self.plan_file), self.cfg)
        return self.c.prepare(plan, str(self.plan_file), start, "zenoh:abc", "ana", name)

    def accept(self, coll: Any, outcome: str = "") -> Any:
        """The loop took the plan; its sequencer as the main thread sees it."""
        seq = SimpleNamespace(plan=coll.plan, outcome=outcome, finished_steps=[],
                              step=coll.plan.steps[0])
        self.d.ctrl.plan_run = seq
        return seq


def test_a_daemon_that_does_not_record_refuses(tmp_path: Path) -> None:
    s = Setup(tmp_path, record=False)
    with pytest.raises(CommandRefused, match="does not record.*--record DIR"):
        s.prepare()
    assert s.sent == []


def test_a_new_collection_its_directory_and_the_recorder_told(tmp_path: Path) -> None:
    s = Setup(tmp_path)
    coll = s.prepare()
    assert os.path.dirname(coll.dir) == str(s.rec) and os.path.isdir(coll.dir)
    assert os.path.basename(coll.dir).startswith("quick-")
    [begin] = s.sent
    assert begin["op"] == "begin" and begin["dir"] == coll.dir and begin["run_name"] == "quick"
    assert [(st["step"], st["index"], st["load_kg"]) for st in begin["steps"]] == [
        ("light", 0, 15.0), ("heavy", 1, 50.0)]
    assert begin["metadata"]["pamd.collection"]["requested_by"] == "zenoh:abc"
    with pytest.raises(CommandRefused, match="still running"):
        s.prepare()
    s.accept(coll)
    reply = s.c.verdict(coll, {"ok": True, "plan": "quick", "steps": 2, "start_step": 0})
    assert reply["collection"] == coll.dir and reply["resumed"] is False
    assert Manifest.load(coll.dir).data["runs"] == []  # written as the plan starts


def test_a_refused_plan_leaves_nothing_and_the_recorder_forgets_it(tmp_path: Path) -> None:
    s = Setup(tmp_path)
    coll = s.prepare()
    reply = s.c.verdict(coll, {"ok": False, "error": "the rig is in FAULT"})
    assert reply == {"ok": False, "error": "the rig is in FAULT"}
    assert os.listdir(s.rec) == [] and s.c.active is None
    assert [m["op"] for m in s.sent] == ["begin", "end"] and s.sent[1]["id"] == coll.id


def test_resume_takes_the_newest_unfinished_collection_of_the_plan(tmp_path: Path) -> None:
    s = Setup(tmp_path)
    with pytest.raises(CommandRefused, match="no unfinished collection of plan 'quick'"):
        s.prepare(start=1)
    made = []
    for status in (("done", "failed"), ("done", "failed"), ("done", "done")):
        m = Manifest.new(str(s.rec / f"c{len(made)}"), load_plan(str(s.plan_file), s.cfg),
                         str(s.plan_file), s.cfg)
        os.makedirs(m.directory)
        for step, st in zip(m.data["steps"], status, strict=True):
            step["status"] = st
        m.save()
        os.utime(m.path, (1000.0 + len(made), 1000.0 + len(made)))
        made.append(m.directory)
    other = PLAN.replace("heavy", "heavier")  # the same name, other steps: not this one
    m = Manifest.new(str(s.rec / "c3"), load_plan(str(s.plan_file), s.cfg), str(s.plan_file),
                     s.cfg)
    os.makedirs(m.directory)
    m.data["steps"][1]["name"] = "heavier"
    m.save()
    os.utime(m.path, (2000.0, 2000.0))
    coll = s.prepare(start=1, text=PLAN)
    assert coll.dir == made[1]  # c2 is finished, c3 has other steps, c1 is newer than c0
    assert s.sent[-1]["dir"] == made[1] and not coll.created
    reply = s.c.verdict(coll, {"ok": False, "error": "no"})
    assert reply["ok"] is False and os.path.isdir(made[1])  # a resumed one stays
    assert s.prepare(start=1, text=other).dir == m.directory  # the plan with its steps


def test_resume_a_named_collection(tmp_path: Path) -> None:
    s = Setup(tmp_path)
    dirs = {}
    for name, status in (("old", ("done", "failed")), ("new", ("done", "failed")),
                         ("finished", ("done", "done"))):
        m = Manifest.new(str(s.rec / name), load_plan(str(s.plan_file), s.cfg),
                         str(s.plan_file), s.cfg)
        os.makedirs(m.directory)
        for step, st in zip(m.data["steps"], status, strict=True):
            step["status"] = st
        m.save()
        dirs[name] = m.directory
    coll = s.prepare(start=1, name="old")  # not the newest: the one asked for
    assert coll.dir == dirs["old"] and not coll.created
    s.c.verdict(coll, {"ok": False, "error": "no"})
    for name, match in (("finished", "is finished"), ("nowhere", "collection 'nowhere'"),
                        ("../rec/old", "not a path"), ("..", "not a path")):
        with pytest.raises(CommandRefused, match=match):
            s.prepare(start=1, name=name)
    with pytest.raises(CommandRefused, match="with other steps"):
        s.prepare(start=1, name="new", text=PLAN.replace("heavy", "heavier"))
    with pytest.raises(CommandRefused, match="only to resume"):
        s.prepare(start=0, name="old")
    assert sorted(os.listdir(s.rec)) == ["finished", "new", "old"]  # nothing new made


def test_a_daemon_stopping_mid_plan_writes_the_manifest_as_it_closes(tmp_path: Path) -> None:
    s = Setup(tmp_path)
    coll = s.prepare()
    s.accept(coll)
    s.c.verdict(coll, {"ok": True})
    step_file = "20250101-000000_sim_quick_01-light.mcap"
    Path(coll.dir, step_file).write_bytes(b"")  # what the io process wrote
    s.d.ctrl.tick_no = 600
    s.d.ctrl.supervisor.fault(0.0, "m1: something")
    s.c.service()  # the plan still runs: nothing yet
    assert Manifest.load(coll.dir).data["runs"] == []
    s.c.close("SIGTERM received")
    m = Manifest.load(coll.dir).data
    [run] = m["runs"]
    assert run["outcome"] == "aborted: the daemon stopped (SIGTERM received)"
    assert run["files"] == [step_file] and run["ticks"] == 500
    assert run["faults"] == ["m1: something"] and run["user"] == "ana"
    assert [(st["status"], st["files"]) for st in m["steps"]] == [
        ("interrupted", [step_file]), ("pending", [])]
    assert s.c.active is None
    # no event: the rings to the io process are gone by then (the daemon's close)
    assert [e["what"] for e in s.events] == ["started"]


def test_the_manifest_waits_for_the_io_process_to_close_the_files(tmp_path: Path) -> None:
    s = Setup(tmp_path)
    coll = s.prepare()
    seq = s.accept(coll)
    s.c.verdict(coll, {"ok": True})
    seq.outcome, seq.finished_steps, seq.step = "done", ["light", "heavy"], None
    s.c.service()
    assert s.sent[-1] == {"op": "end", "id": coll.id}  # never begun? then drop it
    assert Manifest.load(coll.dir).data["runs"] == []  # the files are not closed yet
    s.c.notice({"what": "closed", "id": coll.id + 1, "ticks": 7})  # not this collection's
    s.c.service()
    assert s.c.active is coll
    s.c.notice({"what": "closed", "id": coll.id, "ticks": 4321})
    s.c.service()
    [run] = Manifest.load(coll.dir).data["runs"]
    assert run["outcome"] == "done" and run["ticks"] == 4321 and s.c.active is None
    assert s.events[-1]["what"] == "ended" and s.events[-1]["outcome"] == "done"

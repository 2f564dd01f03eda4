"""`pamd collect` end to end on the simulated rig: dry run, files per step, manifest,
a fault that keeps its files, and --resume from the first unfinished step."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import yaml
from mcap.reader import make_reader

REPO = Path(__file__).resolve().parents[2]
PLAN = """name: quick
muscle: m1
settle: {seconds: 1}
profile: {kind: sine, min_bar: 0.0, max_bar: 3.0, freq_hz: 0.5, cycles: 1}
steps:
  - {name: light, load_kg: 15}
  - name: heavy
    load_kg: 50
    SETTLE
"""
GOOD = PLAN.replace("    SETTLE\n", "")


def faulty_rig(tmp_path: Path) -> Path:
    """The built-in simulated rig whose length encoder dies 8 s in: during step 2."""
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["loop"]["realtime"] = {"enabled": False}
    data["telemetry"] = {"enabled": False}
    data["drivers"][0]["options"]["faults"] = [
        {"at_s": 8.0, "muscle": "m1", "signal": "length", "kind": "dead"}]
    path = tmp_path / "faulty-rig.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def collect(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", "collect", *args, "--no-progress"],
                          capture_output=True, text=True, timeout=180, cwd=REPO)


def test_dry_run_prints_the_timeline_and_moves_nothing(tmp_path: Path) -> None:
    r = collect(str(REPO / "config/experiments/sine-sweep.yaml"), "--dry-run")
    assert r.returncode == 0, r.stderr
    assert "5 steps" in r.stdout and "load-80kg" in r.stdout and "nothing moved" in r.stdout
    assert "sensors read" not in r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("load_kg: 50", "load_kg: 120"))
    r = collect(str(bad), "--dry-run")
    assert r.returncode == 2 and "steps[1] (heavy).load_kg" in r.stderr


def test_collection_writes_a_file_per_step_and_a_manifest(tmp_path: Path) -> None:
    plan = tmp_path / "plan.yaml"
    plan.write_text(GOOD)
    out = tmp_path / "out"
    r = collect(str(plan), "--clock", "virtual", "--out", str(out))
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "manifest.json").read_text())
    assert [(s["name"], s["status"]) for s in m["steps"]] == [("light", "done"),
                                                              ("heavy", "done")]
    for step, load in (("light", "15"), ("heavy", "50")):
        (name,) = next(s for s in m["steps"] if s["name"] == step)["files"]
        with open(out / name, "rb") as fh:
            reader = make_reader(fh)
            meta = {r.name: r.metadata for r in reader.iter_metadata()}
            assert meta["pamd.experiment"]["step"] == step
            assert meta["pamd.experiment"]["load_kg"].startswith(load)
            summary = reader.get_summary()
            topic = {cid: ch.topic for cid, ch in summary.channels.items()}
            counts = {topic[c]: n for c, n in summary.statistics.channel_message_counts.items()}
        # one muscle message per tick: as many as loop-timing messages, no loss
        assert counts["/pamd/sim/state/m1"] == counts["/pamd/sim/loop"] > 1000


def test_a_fault_keeps_its_files_and_resume_finishes_the_plan(tmp_path: Path) -> None:
    plan = tmp_path / "plan.yaml"
    plan.write_text(GOOD)
    out = tmp_path / "out"
    r = collect(str(plan), "--config", str(faulty_rig(tmp_path)), "--clock", "virtual",
                "--out", str(out))
    assert r.returncode == 1 and "fault" in r.stdout
    assert "m1.length reads 0.00 mm" in r.stderr
    m = json.loads((out / "manifest.json").read_text())
    assert [s["status"] for s in m["steps"]] == ["done", "failed"]
    assert all(s["files"] for s in m["steps"])  # the failed step's file is kept
    # the operator replaces the encoder (the built-in rig), then resumes
    r = collect(str(plan), "--clock", "virtual", "--resume", str(out))
    assert r.returncode == 0, r.stderr
    assert "from step 2 (heavy)" in r.stdout
    m = json.loads((out / "manifest.json").read_text())
    assert [s["status"] for s in m["steps"]] == ["done", "done"]
    assert [run["start_step"] for run in m["runs"]] == [0, 1]
    assert len(m["steps"][1]["files"]) == 2  # the failed attempt's and the resumed one's

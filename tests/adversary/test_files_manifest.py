"""Adversary (issue 24, B11): SIGKILL of the process running a collection, then
`pamd inspect` and `--resume`. The manifest is saved each time a step ends, so the
finished step is on record; a manifest left stale all the same (here: rewritten as the
attack found it, every step "pending, files []") is brought in line with the step
files' own metadata, and inspect and resume agree with the files."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from pamd.client.collection import inspect_collection
from pamd.loop.experiment.manifest import Manifest

REPO = Path(__file__).resolve().parents[2]
PLAN = """name: crash
muscle: m1
settle: {seconds: 1}
profile: {kind: sine, min_bar: 0.0, max_bar: 3.0, freq_hz: 0.5, cycles: 1}
steps:
  - {name: light, load_kg: 15}
  - name: heavy
    load_kg: 50
    profile: {kind: sine, min_bar: 0.0, max_bar: 3.0, freq_hz: 0.5, cycles: 40}
"""
# Step 2 is 80 s of rig time (3-4 s of wall time on the virtual clock), so the SIGKILL,
# sent as soon as its file appears, lands inside it even when this test's process waits
# for a core: with 8 cycles (16 s, under a second) a busy machine once let step 2 end
# first, and its file then rightly counted it done. The resume needs no such window:
# it runs the same plan with step 2 at 2 cycles (a resume checks the plan's name, not
# its steps' lengths: the operator may edit a plan between runs, as in
# tests/cli/test_collect_cli.py), not 80 s of rig time again.
RESUMED = PLAN.replace("cycles: 40", "cycles: 2")


def wait_for(check, timeout_s: float, what: str):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            got = check()
        except (OSError, ValueError, KeyError):
            got = None
        if got:
            return got
        time.sleep(0.05)
    raise AssertionError(f"no {what} within {timeout_s} s")


def children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            return [int(p) for p in fh.read().split()]
    except OSError:
        return []


def step_files(files: list[dict]) -> list[str]:  # type: ignore[type-arg]
    return [f["file"] for f in files if "_01-light" in f["file"] or "_02-heavy" in f["file"]]


def test_sigkill_mid_collection_then_inspect_and_resume_agree_with_the_files(
        tmp_path: Path) -> None:
    plan = tmp_path / "plan.yaml"
    plan.write_text(PLAN)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "pamd", "collect", str(plan), "--clock",
                             "virtual", "--out", str(out), "--no-progress"], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    mine: list[int] = []
    try:
        def step_one_on_record() -> bool:
            m = json.loads((out / "manifest.json").read_text())
            heavy = [f for f in os.listdir(out) if f.endswith("_02-heavy.mcap")]
            return m["steps"][0]["status"] == "done" and bool(heavy)

        # saved when the step ended, not when the plan does
        wait_for(step_one_on_record, 120, "manifest with step 1 done and step 2's file")
        mine = children(proc.pid)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(30)
        m = json.loads((out / "manifest.json").read_text())
        assert [s["status"] for s in m["steps"]] == ["done", "pending"]
        assert len(m["steps"][0]["files"]) == 1 and m["runs"] == []
        for pid in mine:  # the io process finalises the files and ends
            wait_for(lambda pid=pid: not os.path.exists(f"/proc/{pid}") or
                     "zombie" in Path(f"/proc/{pid}/status").read_text(), 60,
                     f"process {pid} to end")

        info = inspect_collection(str(out))
        assert info["summary"]["steps_done"] == 1
        assert [s["status"] for s in info["steps"]] == ["done", "interrupted"]
        assert not step_files(info["other_files"])  # every step's file is its step's

        # the manifest as the attack left it: every step pending, no files
        stale = json.loads((out / "manifest.json").read_text())
        for s in stale["steps"]:
            s["status"], s["files"] = "pending", []
        (out / "manifest.json").write_text(json.dumps(stale))
        info = inspect_collection(str(out))
        assert info["summary"]["steps_done"] == 1, info
        assert [s["status"] for s in info["steps"]] == ["done", "interrupted"]
        assert not step_files(info["other_files"]) and info["stale"]
        assert [f["file"] for f in info["steps"][0]["files"]] == m["steps"][0]["files"]
        assert json.loads((out / "manifest.json").read_text()) == stale  # inspect wrote nothing
        assert Manifest.load(str(out), reconcile=True).first_unfinished() == 1

        (out / "manifest.json").write_text(json.dumps(stale))
        plan.write_text(RESUMED)
        r = subprocess.run([sys.executable, "-m", "pamd", "collect", str(plan), "--clock",
                            "virtual", "--resume", str(out), "--no-progress"], cwd=REPO,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        assert "the manifest was stale" in r.stdout and "from step 2 (heavy)" in r.stdout
        done = json.loads((out / "manifest.json").read_text())
        assert [s["status"] for s in done["steps"]] == ["done", "done"]
        assert len(done["steps"][0]["files"]) == 1  # step 1 was not redone
        assert inspect_collection(str(out))["summary"]["steps_done"] == 2
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
        for pid in mine:
            if os.path.exists(f"/proc/{pid}"):
                os.kill(pid, signal.SIGKILL)

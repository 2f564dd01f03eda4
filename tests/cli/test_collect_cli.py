"""`pamd collect` end to end on the simulated rig: dry run, files per step, manifest,
a fault that keeps its files, and --resume from the first unfinished step."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

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
# A stillness that cannot be held long enough (5 s within 0.5 s): the settle times
# out and faults whatever the sensors read.
BAD = PLAN.replace("SETTLE", "settle: {seconds: 0.1, until_still: true, still_for_s: 5, "
                   "timeout_s: 0.5}")


def collect(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", "collect", *args, "--no-progress"],
                          capture_output=True, text=True, timeout=180, cwd=REPO)


def test_dry_run_prints_the_timeline_and_moves_nothing(tmp_path: Path, pamd_here: Any) -> None:
    r = pamd_here("collect", REPO / "config/experiments/sine-sweep.yaml", "--dry-run",
                  "--no-progress", cwd=REPO)
    assert r.returncode == 0, r.stderr
    assert "5 steps" in r.stdout and "load-80kg" in r.stdout and "nothing moved" in r.stdout
    assert "sensors read" not in r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("load_kg: 50", "load_kg: 120"))
    r = pamd_here("collect", bad, "--dry-run", "--no-progress", cwd=REPO)
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
    plan.write_text(BAD)
    out = tmp_path / "out"
    r = collect(str(plan), "--clock", "virtual", "--out", str(out))
    assert r.returncode == 1 and "fault" in r.stdout
    m = json.loads((out / "manifest.json").read_text())
    assert [s["status"] for s in m["steps"]] == ["done", "failed"]
    assert all(s["files"] for s in m["steps"])  # the failed step's file is kept
    # the manifest is as readable as the recordings it lists (not mkstemp's 0600)
    step_file = out / m["steps"][0]["files"][0]
    assert (out / "manifest.json").stat().st_mode & 0o777 == step_file.stat().st_mode & 0o777
    # --out into a collection that exists is refused: its manifest is not overwritten
    before = (out / "manifest.json").read_text()
    r = collect(str(plan), "--clock", "virtual", "--out", str(out))
    assert r.returncode == 4 and f"--resume {out}" in r.stderr, r.stderr
    assert (out / "manifest.json").read_text() == before
    plan.write_text(GOOD)  # the operator fixes the plan, then resumes
    r = collect(str(plan), "--clock", "virtual", "--resume", str(out))
    assert r.returncode == 0, r.stderr
    assert "from step 2 (heavy)" in r.stdout
    m = json.loads((out / "manifest.json").read_text())
    assert [s["status"] for s in m["steps"]] == ["done", "done"]
    assert [run["start_step"] for run in m["runs"]] == [0, 1]
    assert len(m["steps"][1]["files"]) == 2  # the failed attempt's and the resumed one's


def test_ctrl_c_is_acknowledged_at_once_and_pauses_a_one_cycle_step(tmp_path: Path) -> None:
    rig = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    rig["loop"].update(rate_hz=250, stall_timeout_s=1.0, realtime={"enabled": False})
    rig["safety"].update(signal_timeout_s=0.5)
    rig["telemetry"] = {"enabled": False}
    (tmp_path / "rig.yaml").write_text(yaml.safe_dump(rig, sort_keys=False))
    plan = tmp_path / "plan.yaml"
    plan.write_text("""name: one
muscle: m1
settle: {seconds: 0.5}
profile: {kind: sine, min_bar: 0.0, max_bar: 2.0, freq_hz: 0.2, cycles: 1}
steps:
  - {name: only}
""")
    proc = subprocess.Popen(
        [sys.executable, "-m", "pamd", "collect", str(plan), "--config",
         str(tmp_path / "rig.yaml"), "--out", str(tmp_path / "out"), "--no-progress"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        cwd=REPO, env={**os.environ, "PYTHONUNBUFFERED": "1", "PAMD_OPERATOR_STDIN": "1"})
    assert proc.stderr is not None and proc.stdin is not None and proc.stdout is not None
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(proc.stderr.readline, "")),
                              daemon=True)
    reader.start()

    def said(text: str, within_s: float) -> bool:
        deadline = time.monotonic() + within_s
        while time.monotonic() < deadline:
            if any(text in line for line in list(err)):
                return True
            time.sleep(0.05)
        return False

    try:
        assert said("IDLE -> RUNNING: plan step only", 60), err
        time.sleep(1.5)  # inside the step's only cycle (lead-in, then 5 s of sine)
        proc.send_signal(signal.SIGINT)
        assert said("pausing at the end of the present cycle", 5), err  # at once
        proc.stdin.write("r\n")  # answers the pause menu, shown once the cycle ends
        proc.stdin.flush()
        out = proc.stdout.read()
        proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    reader.join(10)
    assert "paused at the end of the cycle: [r]esume or [a]bort?" in out, (out, err)
    assert any("paused at the end of the cycle (the step's last)" in ln for ln in err), err
    assert proc.returncode == 0, (out, err)
    m = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert [s["status"] for s in m["steps"]] == ["done"]


def test_the_progress_bar_never_passes_its_total() -> None:
    """Every collect ended with `TqdmWarning: clamping frac to range [0, 1]` and a
    negative ETA (issue 40): the bar's total is the timeline's rounded to 0.1 s, the
    rig time ran past it; the count is held to the bar's own total."""
    import io
    import warnings

    from pamd.client.cli.collect import _bar, show_rig_time

    for total_s, ran_s in ((371.04, 371.07), (20.0, 20.3), (12.5, 3.0)):
        bar = _bar(total_s, True)
        assert bar is not None
        bar.fp = io.StringIO()  # type: ignore[attr-defined]
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            show_rig_time(bar, ran_s)
            bar.set_postfix_str("step 1/1", refresh=True)
            text = bar.fp.getvalue()  # type: ignore[attr-defined]
            bar.close()
        assert bar.n == min(ran_s, bar.total) and "<-" not in text, text

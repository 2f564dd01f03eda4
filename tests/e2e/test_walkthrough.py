"""The README's walk-through, shortened, on the simulated rig with the virtual clock:
collect a sweep under three loads -> train the inverse model on the collection ->
track a length profile with the model as feedforward (recorded) -> evaluate the
model on that run. Every step through the real command line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PLAN = """name: walk
muscle: m1
settle: {seconds: 2}
profile: {kind: sine, min_bar: 0.0, max_bar: 5.0, freq_hz: 0.1, cycles: 2}
steps:
  - {name: light, load_kg: 20}
  - {name: mid, load_kg: 30}
  - {name: heavy, load_kg: 40}
"""


def pamd(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-m", "pamd", *args], capture_output=True, text=True,
                       timeout=300, cwd=REPO, env=env)
    assert r.returncode == 0, f"pamd {' '.join(args)}:\n{r.stdout}\n{r.stderr}"
    return r


def test_collect_train_track_evaluate(tmp_path: Path) -> None:
    plan = tmp_path / "plan.yaml"
    plan.write_text(PLAN)
    sweep = tmp_path / "sweep"
    pamd("collect", str(plan), "--clock", "virtual", "--out", str(sweep), "--no-progress")
    manifest = json.loads((sweep / "manifest.json").read_text())
    files = [str(sweep / f) for s in manifest["steps"] for f in s["files"]]
    assert len(files) == 3

    model = tmp_path / "model.json"
    # Three loads support a 3 x 3 rule grid; a finer grid leaves rules without data.
    pamd("train", *files, "--out", str(model), "--epochs", "30", "--mfs", "3", "--quiet")
    m = json.loads(model.read_text())
    assert m["format"] == "pamd-anfis" and [i["name"] for i in m["inputs"]] == [
        "force_n", "length_mm"]

    track = tmp_path / "track"
    r = pamd("run", "--clock", "virtual", "--mode", "position", "--model", str(model),
             "--profile", "sine", "--freq-hz", "0.1", "--min-contraction", "0.05",
             "--max-contraction", "0.15", "--cycles", "2", "--record", str(track),
             "--no-telemetry", "--json")
    summary = json.loads(r.stdout)
    assert summary["final_state"] == "IDLE" and summary["faults"] == []

    r = pamd("evaluate", str(model), *map(str, track.glob("*.mcap")), "--json",
             "--plot", str(tmp_path / "eval"))
    metrics = json.loads(r.stdout)
    # The model predicts the pressure the tracked run needed, as well as a 2-input 3 x 3
    # model of three loads can: it cannot see which hysteresis branch it is on, and at
    # the top of the stroke it is fed the raw force, which swings with the load by
    # +-20 N while the tick feeds it low-passed (0.86 bar RMSE on the flow plant; 0.36
    # on the old lag plant, where the load rang less).
    assert 0.0 < metrics["rmse"] < 1.0 and metrics["nrmse_fit_pct"] > -60.0
    assert set(metrics) >= {"mse", "rmse", "mae", "max_abs_error", "max_deviation_pct",
                            "sse", "nrmse_fit_pct", "aic", "sbc", "ndei"}
    for part in ("prediction", "error", "membership", "surface"):
        png = tmp_path / f"eval_{part}.png"
        assert png.stat().st_size > 5000

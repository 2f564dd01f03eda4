"""The model's training domain through the command line: `pamd run --off-data` and the
summary's `feedforward` per muscle, an older model file run with what it lacks said, a
model whose domain the muscle cannot reach refused before anything moves, and `pamd
train` on fewer samples than parameters (a warning, not a refusal)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pamd.models.anfis import TrainingOptions, fit, save
from pamd.models.domain import derive

FIXTURES = Path(__file__).resolve().parents[1] / "control" / "fixtures"
TRACK = ("run", "--clock", "virtual", "--mode", "position", "--profile", "sine",
         "--min-contraction", "0.06", "--max-contraction", "0.12", "--freq-hz", "0.25",
         "--cycles", "1", "--json", "--no-record", "--no-telemetry")


def test_an_older_model_runs_with_what_it_lacks_said_and_the_summary_counts(
        pamd_here: Callable[..., Any]) -> None:
    r = pamd_here(*TRACK, "--model", FIXTURES / "walkthrough-3x3x3.json", "--off-data",
                  "warn")
    assert r.returncode == 0, r.stderr
    assert "carries no training domain" in r.stderr and "coverage grid" in r.stderr
    ff = json.loads(r.stdout)["feedforward"]["m1"]
    assert ff["off_data"] == "warn" and ff["faded_pct"] == 0 and ff["ticks"] > 3000
    assert 0 <= ff["off_data_pct"] < 100 and ff["oscillations"] == 0


def test_the_pid_alone_has_nothing_to_judge(pamd_here: Callable[..., Any]) -> None:
    r = pamd_here(*TRACK, "--no-feedforward")
    assert r.returncode == 0, r.stderr
    ff = json.loads(r.stdout)["feedforward"]["m1"]
    assert ff["ticks"] == 0 and ff["off_data_pct"] is None and ff["faded_pct"] is None


def test_a_domain_the_muscle_cannot_reach_is_refused_naming_the_inputs(
        tmp_path: Path, pamd_here: Callable[..., Any]) -> None:
    """Trained on 7-9 bar under 2-2.5 kN (another muscle): every length in this one's
    travel, but neither its pressure limit (6 bar) nor its force (1.5 kN at most)."""
    rng = np.random.default_rng(0)
    X = np.c_[rng.uniform(2000.0, 2500.0, 200), rng.uniform(165.0, 200.0, 200)]
    y = 7.0 + (200.0 - X[:, 1]) / 17.5
    names = ["force_n", "length_mm"]
    model = fit(X, y, TrainingOptions(n_mfs=2, epochs=2), input_names=names,
                input_units=["N", "mm"], output_name="pressure_bar", output_unit="bar",
                provenance={"domain": derive(X, y, names, "pressure_bar").to_json()}).model
    path = save(model, tmp_path / "other.json")
    r = pamd_here(*TRACK, "--model", path)
    assert r.returncode != 0 and "sensors read" not in r.stderr  # nothing started
    assert "force_n" in r.stderr and "pressure_bar" in r.stderr
    assert "lies outside what this muscle reaches" in r.stderr


def test_train_with_fewer_samples_than_parameters_warns_and_writes(
        tmp_path: Path, pamd_here: Callable[..., Any]) -> None:
    rng = np.random.default_rng(1)
    f, ln = rng.uniform(100, 700, 60), rng.uniform(160, 200, 60)
    rows = ["force_n,length_mm,pressure_bar"] + [
        f"{a!r},{b!r},{a / 300 + (200 - b) / 10!r}" for a, b in zip(f.tolist(), ln.tolist(),
                                                               strict=True)]
    table = tmp_path / "few.csv"
    table.write_text("\n".join(rows) + "\n")
    out = tmp_path / "m.json"
    r = pamd_here("train", table, "--out", out, "--inputs", "force_n,length_mm", "--mfs", "5",
                  "--val-split", "0", "--epochs", "2", "--quiet")
    assert r.returncode == 0, r.stderr
    assert "WARNING: 60 samples for a model with 95 parameters" in r.stderr
    assert json.loads(out.read_text())["provenance"]["training"]["warnings"]

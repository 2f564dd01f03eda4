"""`pamd train` and `pamd evaluate` end to end on a short recorded run."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pamd.client.cli.main import main
from pamd.models.anfis import load
from pamd.models.metrics import METRIC_NAMES
from pamd.wire.tick import Flag
from tests.models.anfis.test_dataset import write_csv


def test_train_then_evaluate_with_json_and_plots(recording: Path, tmp_path: Path,
                                                 capsys: Any) -> None:
    model_path = tmp_path / "m.json"
    assert main(["train", str(recording), "--out", str(model_path), "--inputs",
                 "force_n,length_mm,velocity_mm_s", "--mfs", "2,3,2", "--epochs", "8",
                 "--val-split", "0.25", "--block-s", "1", "--settle-s", "0.5"]) == 0
    out, err = capsys.readouterr()
    assert "epoch" in err and "train RMSE" in err and "val RMSE" in err  # the progress bar
    # a bar per phase, each with its total (issue 40: 100/100, then 101 ... 200 epochs
    # of a second start with no total): reading, then each of ANFIS's two starts
    assert "reading 1 file(s)" in err
    for k in (1, 2):
        assert f"training, start {k}/2: 100%" in err
    assert re.findall(r"\| *(\d+)/8 \[", err)[-1] == "8"
    assert not re.search(r"\| *(9|1\d)/8 \[", err)
    for label in ("RMSE", "NRMSE fit %", "AIC", "SBC", "NDEI", "validation"):
        assert label in out
    model = load(model_path)
    # the closing line's time is the command's wall time, not one start's training time
    said = re.search(r"; ([\d.]+) s \(wall time, reading included\)", out)
    assert said, out
    assert float(said.group(1)) >= model.provenance["training"]["seconds"]
    assert [v.name for v in model.inputs] == ["force_n", "length_mm", "velocity_mm_s"]
    assert model.n_mfs == (2, 3, 2)
    assert model.derived_inputs["velocity_mm_s"]["window_s"] > 0
    prov = model.provenance
    assert prov["data"]["files"] == [str(recording)] and prov["data"]["loads_kg"] == [30.0]
    assert len(prov["training_curve"]["train_rmse"]) == 8
    assert prov["split"]["by"] == "block" and prov["split"]["validation_samples"] > 0

    prefix = tmp_path / "figs" / "m"
    assert main(["evaluate", str(model_path), str(recording), "--json", "--plot",
                 str(prefix)]) == 0
    out, err = capsys.readouterr()
    doc = json.loads(out)
    metrics = {k: v for k, v in doc.items() if k not in ("models", "samples")}
    assert set(metrics) == set(METRIC_NAMES)
    [entry] = doc["models"]  # the same figures in the list form of several models
    assert doc["samples"] == entry["samples"] == entry["tick"]["samples"] > 0
    assert entry["kind"] == "anfis" and entry["file"] == str(model_path)
    assert entry["n_params"] == load(model_path).n_params and entry["metrics"] == metrics
    assert entry["tick_cost_us"] > 0
    assert metrics["rmse"] < 0.5 and metrics["mse"] == pytest.approx(metrics["rmse"] ** 2)
    for part in ("prediction", "error", "membership", "surface", "training"):
        png = Path(f"{prefix}_{part}.png")
        assert png.exists() and png.stat().st_size > 5000, png
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_train_on_all_data_and_table_without_json(recording: Path, tmp_path: Path,
                                                  capsys: Any) -> None:
    model_path = tmp_path / "m2.json"
    assert main(["train", str(recording), "--out", str(model_path), "--val-split", "0",
                 "--mfs", "3", "--epochs", "3", "--quiet"]) == 0
    model = load(model_path)
    assert model.n_rules == 27 and "validation" not in model.metrics  # 3 inputs: default
    assert model.provenance["split"]["validation_samples"] == 0
    capsys.readouterr()
    assert main(["evaluate", str(model_path), str(recording)]) == 0
    out = capsys.readouterr().out
    assert "max deviation %" in out and "evaluation" in out


def test_a_lab_table_on_onoff_valves_trains_and_evaluates_as_one(
        tmp_path: Path, capsys: Any) -> None:
    """`--actuation onoff` keeps a lab table's exhaust-flagged samples (the PWM's own
    pulses); the model file says so, and `pamd evaluate` reads the table the same way
    without being told again. A pamd recording's own config wins, and is said."""
    flags = np.zeros(3000)
    flags[500:1500] = int(Flag.EXHAUST_OPEN)  # 10 s of the PWM's venting pulses
    lab = write_csv(tmp_path / "lab.csv", flags=flags)
    model_path = tmp_path / "m.json"
    args = ["train", str(lab), "--out", str(model_path), "--mfs", "2", "--epochs", "2",
            "--quiet", "--val-split", "0"]
    assert main([*args, "--out", str(tmp_path / "plain.json")]) == 0
    assert main([*args, "--actuation", "onoff"]) == 0
    data = load(model_path).provenance["data"]
    plain = load(tmp_path / "plain.json").provenance["data"]
    assert data["extraction"]["actuation"] == "onoff" and data["runs"][0]["actuation"] == "onoff"
    assert data["samples"] >= plain["samples"] + 450  # 10 s at 50 Hz no longer dropped
    capsys.readouterr()
    assert main(["evaluate", str(model_path), str(lab), "--json", "--no-timing"]) == 0
    assert f"{data['samples']} samples" in capsys.readouterr().err
    assert main(["evaluate", str(model_path), str(lab), "--json", "--no-timing",
                 "--actuation", "proportional"]) == 0
    assert f"{plain['samples']} samples" in capsys.readouterr().err


def test_the_actuation_option_does_not_override_a_recordings_config(
        recording: Path, tmp_path: Path, capsys: Any) -> None:
    assert main(["train", str(recording), "--out", str(tmp_path / "m.json"), "--mfs", "2",
                 "--epochs", "1", "--quiet", "--val-split", "0", "--actuation", "onoff"]) == 0
    err = capsys.readouterr().err
    assert "its config says actuation: proportional, kept" in err
    runs = load(tmp_path / "m.json").provenance["data"]["runs"]
    assert [r["actuation"] for r in runs] == ["proportional"]


@pytest.mark.parametrize("args, message", [
    (["--inputs", "force_n,stiffness"], "unknown input(s) stiffness"),
    (["--mfs", "5,5"], "2 numbers for 3 inputs"),
    (["--val-split", "1.5"], "fraction must be in [0, 1)"),
])
def test_bad_train_options_are_refused(recording: Path, tmp_path: Path, capsys: Any,
                                       args: list[str], message: str) -> None:
    code = main(["train", str(recording), "--out", str(tmp_path / "x.json"), "--quiet", *args])
    assert code == 5
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_bad_data_and_model_files_are_refused(tmp_path: Path, capsys: Any) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,force_n,length_mm\n0,1,2\n0.1,1,2\n")
    assert main(["train", str(bad), "--out", str(tmp_path / "m.json"), "--quiet"]) == 5
    assert "missing column(s) pressure_bar" in capsys.readouterr().err
    junk = tmp_path / "junk.json"
    junk.write_text("{not json")
    assert main(["evaluate", str(junk), str(bad)]) == 5
    assert "not valid JSON" in capsys.readouterr().err

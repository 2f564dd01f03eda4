"""`pamd train` and `pamd evaluate` end to end on a short recorded run."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from pamd.cli.main import main
from pamd.metrics import METRIC_NAMES
from pamd.models.anfis import load


def test_train_then_evaluate_with_json_and_plots(recording: Path, tmp_path: Path,
                                                 capsys: Any) -> None:
    model_path = tmp_path / "m.json"
    assert main(["train", str(recording), "--out", str(model_path), "--inputs",
                 "force_n,length_mm,velocity_mm_s", "--mfs", "2,3,2", "--epochs", "8",
                 "--val-split", "0.25", "--block-s", "1", "--settle-s", "0.5"]) == 0
    out, err = capsys.readouterr()
    assert "epoch" in err and "train RMSE" in err and "val RMSE" in err  # the progress bar
    for label in ("RMSE", "NRMSE fit %", "AIC", "SBC", "NDEI", "validation"):
        assert label in out
    model = load(model_path)
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
    metrics = {k: v for k, v in doc.items() if k != "models"}
    assert set(metrics) == set(METRIC_NAMES)
    [entry] = doc["models"]  # the same figures in the list form of several models
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
    assert model.n_rules == 9 and "validation" not in model.metrics
    assert model.provenance["split"]["validation_samples"] == 0
    capsys.readouterr()
    assert main(["evaluate", str(model_path), str(recording)]) == 0
    out = capsys.readouterr().out
    assert "max deviation %" in out and "evaluation" in out


@pytest.mark.parametrize("args, message", [
    (["--inputs", "force_n,stiffness"], "unknown input(s) stiffness"),
    (["--mfs", "5,5,5"], "3 numbers for 2 inputs"),
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

"""The papers' protocols as options of pamd (issue 46 item 2), each tested both ways:
the random split (`pamd train --split-by random`, 70/15/15 by default, reproducible by
its seed), the metric basis (`pamd evaluate --held-out all|validation|test`, its JSON's
`samples`), seed 001's change of length (`delta_length_mm`) and its halved MSE
(`half_mse`), seed 000's MATLAB preset; a split that leaves a part empty and data that
are not the model's training data are refused."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pamd
from pamd.client.cli.main import main
from pamd.client.training_tables import load_samples
from pamd.models.anfis.hybrid import premise_units, raw_step
from pamd.models.anfis_kind import AnfisOptions
from pamd.models.data.extraction import delta_length
from pamd.models.data.samples import ExtractOptions, Samples
from pamd.models.data.splitting import default_fractions, resplit, split
from pamd.models.metrics import regression_metrics
from pamd.models.registry import load_model
from pamd.wire.errors import ModelError

MAP = str(Path(pamd.__file__).parent / "data" / "dmsp20_force_map.csv")  # 58 points
FORWARD = ["--target", "force_n", "--inputs", "pressure_bar,contraction"]


def samples(n: int, runs: int = 1) -> Samples:
    run = np.repeat(np.arange(runs), n // runs)
    x = np.linspace(0.0, 1.0, run.size)
    return Samples(X=x[:, None], y=2.0 * x, t_s=np.arange(run.size, dtype=float), run=run,
                   inputs=("length_mm",), output="pressure_bar",
                   runs=[{"source": f"r{k}"} for k in range(runs)], options=ExtractOptions())


def test_the_random_split_is_the_papers_and_reproducible_by_its_seed() -> None:
    assert default_fractions("random", None, None) == (0.15, 0.15)
    assert default_fractions("block", None, None) == (0.2, 0.0)
    assert default_fractions("random", 0.1, None) == (0.1, 0.15)
    s = samples(455)  # seed 002's DMSP-20 data: 319/68/68 in its Table 4
    a = split(s, *default_fractions("random", None, None), by="random", seed=3)
    assert (len(a.train), a.how["validation_samples"], a.how["test_samples"]) == (319, 68, 68)
    b = split(s, 0.15, 0.15, by="random", seed=3)
    c = split(s, 0.15, 0.15, by="random", seed=4)
    assert a.in_test is not None and b.in_test is not None and c.in_test is not None
    assert np.array_equal(a.in_test, b.in_test) and np.array_equal(a.in_validation,
                                                                    b.in_validation)
    assert not np.array_equal(a.in_test, c.in_test)  # another seed, other samples
    assert not (a.in_test & a.in_validation).any()
    # single samples, not blocks: the test rows are scattered over the whole record
    assert np.diff(np.flatnonzero(a.in_test)).min() == 1 < np.diff(
        np.flatnonzero(a.in_test)).max()
    # the parts come back from the model file's settings, and only from the same data
    again = resplit(s, a.how, "m.json")
    assert again.in_test is not None and np.array_equal(again.in_test, a.in_test)
    with pytest.raises(ModelError, match="give the data it was trained on"):
        resplit(samples(454), a.how, "m.json")
    with pytest.raises(ModelError, match="m.json: its file does not say how"):
        resplit(s, {}, "m.json")


def test_a_split_that_leaves_a_part_empty_is_refused() -> None:
    one_run = samples(100, runs=1)
    with pytest.raises(ModelError, match="only 1 runs in the data: too few to hold out"):
        split(one_run, 0.2, 0.0, by="run")
    with pytest.raises(ModelError, match="only 2 samples in the data"):
        split(samples(2), 0.15, 0.15, by="random")
    with pytest.raises(ModelError, match="leave nothing to train on"):
        split(one_run, 0.5, 0.5, by="random")
    ok = split(samples(100, runs=2), 0.2, 0.0, by="run")  # two runs: one for each part
    assert len(ok.train) == 50 and ok.validation is not None and len(ok.validation) == 50
    assert ok.test is None  # a share of 0 asks for no part: nothing is refused


def evaluate_json(capsys: Any, *argv: str) -> dict[str, Any]:
    capsys.readouterr()
    assert main(["evaluate", *argv, "--json", "--no-timing"]) == 0
    doc: dict[str, Any] = json.loads(capsys.readouterr().out)
    return doc


def test_held_out_parts_and_all_reproduce_the_training_figures(tmp_path: Path,
                                                               capsys: Any) -> None:
    """--held-out validation / test find the random split's parts again (the same
    figures as training reported), --held-out all is the in-sample basis."""
    model_path = str(tmp_path / "p.json")
    assert main(["train", MAP, "--out", model_path, "--kind", "polynomial", *FORWARD,
                 "--split-by", "random", "--seed", "2", "--quiet"]) == 0
    model = load_model(model_path)
    how = model.provenance["split"]
    assert (how["by"], how["seed"], how["validation_fraction"], how["test_fraction"]) == (
        "random", 2, 0.15, 0.15)
    assert (how["train_samples"], how["validation_samples"], how["test_samples"]) == (
        40, 9, 9)
    for part in ("validation", "test"):
        doc = evaluate_json(capsys, model_path, MAP, "--held-out", part)
        assert doc["samples"] == doc["models"][0]["samples"] == 9
        for key in ("mse", "sse", "nrmse_fit_pct", "aic"):
            assert doc[key] == pytest.approx(model.metrics[part][key], rel=1e-12), (part, key)
    everything = evaluate_json(capsys, model_path, MAP, "--held-out", "all")
    assert everything["samples"] == 58
    held_out = evaluate_json(capsys, model_path, MAP, "--held-out", "test")
    assert held_out["sse"] < everything["sse"]  # 9 of the 58 points' squared errors

    # in-sample: trained on every point, judged on every point
    in_sample = str(tmp_path / "all.json")
    assert main(["train", MAP, "--out", in_sample, "--kind", "polynomial", *FORWARD,
                 "--val-split", "0", "--quiet"]) == 0
    fitted = load_model(in_sample)
    doc = evaluate_json(capsys, in_sample, MAP, "--held-out", "all")
    assert doc["samples"] == 58
    for key in ("mse", "sse", "aic", "sbc", "half_mse"):
        assert doc[key] == pytest.approx(fitted.metrics["train"][key], rel=1e-12), key
    # seed 002's n from its AIC and SBC: exp((SBC - AIC) / p + 2) is the count they cover
    n = np.exp((doc["sbc"] - doc["aic"]) / fitted.n_params + 2.0)
    assert n == pytest.approx(58)
    capsys.readouterr()
    assert main(["evaluate", in_sample, MAP, "--held-out", "test", "--no-timing"]) == 5
    assert "held out no test part (train it with --test-split above 0)" in \
        capsys.readouterr().err


def test_held_out_parts_refuse_other_data(tmp_path: Path, capsys: Any) -> None:
    model_path = str(tmp_path / "p.json")
    assert main(["train", MAP, "--out", model_path, "--kind", "polynomial", *FORWARD,
                 "--split-by", "random", "--quiet"]) == 0
    other = tmp_path / "less.csv"  # the map less its last point
    lines = Path(MAP).read_text().splitlines()
    other.write_text("\n".join(lines[:-1]) + "\n")
    capsys.readouterr()
    assert main(["evaluate", model_path, str(other), "--held-out", "test",
                 "--no-timing"]) == 5
    assert "give the data it was trained on" in capsys.readouterr().err


def test_seed_001s_mse_is_half_pamds_and_named_so() -> None:
    m = regression_metrics([1.0, 2.0, 3.0], [1.5, 2.0, 2.0], n_params=1)
    assert m["half_mse"] == pytest.approx(m["mse"] / 2) == pytest.approx((0.25 + 1) / 6)


def test_delta_length_is_the_change_over_one_sample_period(tmp_path: Path) -> None:
    t = np.arange(0.0, 10.0, 0.001)  # a 1 kHz record of a 2 mm/s ramp
    length = 150.0 + 2.0 * t
    d = delta_length(t, length, rate_hz=50.0)
    assert np.isnan(d[:20]).all() and np.allclose(d[20:], 2.0 / 50.0)  # 0.04 mm a sample
    rows = delta_length(t[:4], np.array([1.0, 1.5, 1.2, 2.0]), 50.0, rows=True)
    assert np.isnan(rows[0]) and np.allclose(rows[1:], [0.5, -0.3, 0.8])
    # from a table: the first sample period is dropped, the rest at the model's rate
    table = tmp_path / "run.csv"
    tt = np.arange(0.0, 20.0, 0.01)
    ln = 150.0 + 10.0 * np.sin(0.2 * np.pi * tt)
    f = 300.0 + 5.0 * np.cos(0.2 * np.pi * tt)
    table.write_text("t_s,force_n,length_mm,pressure_bar\n" + "\n".join(
        f"{a:.2f},{b:.6f},{c:.6f},{3 + 0.1 * c - 15:.6f}" for a, b, c in zip(tt, f, ln,
                                                                            strict=True)))
    s = load_samples([str(table)], ExtractOptions(
        inputs=("force_n", "length_mm", "delta_length_mm"), rate_hz=10.0, settle_s=0.0),
        report=lambda _line: None)
    dl = s.X[:, 2]
    want = np.interp(s.t_s, tt, ln) - np.interp(s.t_s - 0.1, tt, ln)
    assert s.t_s[0] >= 0.1 and np.allclose(dl, want, atol=2e-6)  # 6 decimals written
    with pytest.raises(ModelError, match="missing column"):
        load_samples([str(table)], ExtractOptions(inputs=("force_n", "delta_length_mm"),
                                                  output="contraction"),
                     report=lambda _line: None)


def test_matlab_preset_is_genfis1_one_start_ten_epochs_raw_steps() -> None:
    o = AnfisOptions(preset="matlab").training(2, seed=0)
    assert (o.width_factor, o.epochs, o.step_units, o.initial_step) == (1.0, 10, "raw", 0.01)
    mine = AnfisOptions().training(2, seed=0)
    assert (mine.width_factor, mine.epochs, mine.step_units) == ((1.0, 3.0), 100, "scaled")
    assert AnfisOptions(preset="matlab", epochs=30).training(2, 0).epochs == 30
    # a raw step of length 1: the scaled step times each parameter's unit has norm 1
    units = np.array([800.0, 800.0, 50.0, 50.0])  # N, N, mm, mm per scaled unit
    g = np.array([1.0, -2.0, 0.5, 3.0])
    step = raw_step(g, units)
    assert np.linalg.norm(step * units) == pytest.approx(1.0)
    assert np.all(np.sign(step) == np.sign(g))


def test_matlab_preset_trains_one_start_on_the_inputs_units(tmp_path: Path,
                                                            capsys: Any) -> None:
    out = tmp_path / "m.json"
    assert main(["train", MAP, "--out", str(out), "--inputs", "force_n,contraction",
                 "--mfs", "3", "--preset", "matlab", "--val-split", "0", "--quiet"]) == 0
    model = load_model(out)
    training = model.provenance["training"]
    assert training["width_starts"]["widths"] == [1.0]
    assert training["options"]["step_units"] == "raw" and training["epochs_run"] == 10
    assert premise_units(model).tolist()[:3] == [model.scale_span[0]] * 3

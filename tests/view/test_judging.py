"""Models judged as the tick runs them (pamd.client.judging): the feedforward stage's own
clamps, counted; points off the training data jointly, warned of; a fit worse than a
constant refused by `pamd train`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import pamd
from pamd.client.cli.main import main
from pamd.client.judging import judge_as_tick, off_data, poor_fit
from pamd.client.training_tables import load_samples
from pamd.loop.control.feedforward import Feedforward
from pamd.models.contract import Variable
from pamd.models.data.samples import ExtractOptions
from pamd.models.domain import derive
from pamd.models.registry import load_model

MAP = Path(pamd.__file__).parent / "data" / "dmsp20_force_map.csv"
OPTS = ExtractOptions(inputs=("force_n", "contraction"), output="pressure_bar")


def write_table(path: Path, X: np.ndarray, y: np.ndarray) -> Path:
    lines = ["force_n,contraction,pressure_bar"]
    lines += [f"{f!r},{x!r},{p!r}" for (f, x), p in zip(X.tolist(), y.tolist(), strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def map_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("judging") / "map.json"
    assert main(["train", str(MAP), "--out", str(out), "--inputs", "force_n,contraction",
                 "--mfs", "3", "--block-s", "8", "--quiet"]) == 0
    return out


def test_the_tick_s_clamps_are_the_feedforward_s(map_model: Path, tmp_path: Path) -> None:
    """Outside the map (twice the forces, a bigger muscle's), the model alone answers
    far outside 0-6 bar; evaluated as the tick runs it, the output is held to its
    training range, exactly as `Feedforward.pressure` holds it, and counted."""
    model = load_model(map_model)
    rng = np.random.default_rng(1)
    X = np.c_[rng.uniform(-300, 4000, 200), rng.uniform(-0.04, 0.25, 200)]
    table = write_table(tmp_path / "big.csv", X, rng.uniform(0, 6, 200))
    samples = load_samples([str(table)], OPTS)
    ((judged, rep),) = judge_as_tick(["m.json"], [model], samples, timing=False)
    ff = Feedforward(model)
    want = [ff.pressure(f, float("nan"), x, float("nan")) for f, x in samples.X.tolist()]
    np.testing.assert_array_equal(judged.y_hat, want)
    alone = model.predict(samples.X)
    assert alone.max() > 6.5 or alone.min() < -0.5  # the model alone is lost out there
    lo, hi = model.output.min, model.output.max
    assert judged.y_hat.min() >= lo and judged.y_hat.max() <= hi
    assert rep.output_held == int(((alone > hi) | (alone < lo)).sum()) > 0
    assert rep.inputs_held == int(((X[:, 0] > model.inputs[0].max)
                                   | (X[:, 0] < model.inputs[0].min)).sum()) > 0
    assert rep.model_alone["rmse"] > judged.metrics["rmse"]
    assert any("the output was held" in w for w in rep.warnings("m.json"))


def test_points_off_the_data_jointly_are_found() -> None:
    """Training on a diagonal band of a square: a point in the empty corner is inside
    each input's range but off the data; a point on the band is not; nor is a pressure
    outside the one seen there."""
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 1, 2000)
    X = np.c_[a, a + rng.uniform(-0.05, 0.05, 2000)]
    y = 2.0 + X[:, 1]

    class M:
        provenance = {"domain": derive(X, y, ["force_n", "contraction"],
                                       "pressure_bar").to_json()}
        inputs = [Variable("force_n", "N", 0, 1), Variable("contraction", "", -0.05, 1.05)]
        output = Variable("pressure_bar", "bar", 2.0, 3.0)

    test = np.array([[0.9, 0.1], [0.1, 0.9], [0.5, 0.5], [0.2, 0.21], [0.95, 0.96],
                     [0.5, 0.5]])
    y_hat = np.array([2.5, 2.5, 2.5, 2.2, 2.9, 4.0])
    mask = off_data(M(), test, y_hat)  # type: ignore[arg-type]
    assert mask.tolist() == [True, True, False, False, False, True]


def test_evaluate_warns_off_the_data_and_not_between_loads(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A model of a smooth surface trained on two separate bands of force: a test on the
    same bands is not warned of, nor one between them (interpolating between two loads
    is the model's job); one beyond the heavier band (each input in range: the force
    held) is."""
    rng = np.random.default_rng(2)

    def surface(n: int, f_lo: float, f_hi: float) -> tuple[np.ndarray, np.ndarray]:
        X = np.c_[rng.uniform(f_lo, f_hi, n), rng.uniform(0.0, 0.2, n)]
        return X, 0.004 * X[:, 0] + 10.0 * X[:, 1]

    Xa, ya = surface(600, 100, 200)
    Xb, yb = surface(600, 600, 700)
    train = write_table(tmp_path / "train.csv", np.r_[Xa, Xb], np.r_[ya, yb])
    model = tmp_path / "m.json"
    assert main(["train", str(train), "--out", str(model), "--inputs", "force_n,contraction",
                 "--mfs", "2", "--quiet"]) == 0
    assert "domain" in json.loads(model.read_text())["provenance"]
    capsys.readouterr()
    for lo, hi in ((100, 200), (300, 450)):  # a band trained on, and between the bands
        Xs, ys = surface(300, lo, hi)
        same = write_table(tmp_path / "same.csv", Xs, ys)
        assert main(["evaluate", str(model), str(same), "--no-timing"]) == 0
        out = capsys.readouterr()
        assert "0 (0.0 %) off the training data" in out.out and "warning" not in out.err
    Xg, yg = surface(300, 800, 900)  # heavier than the heavier band
    gap = write_table(tmp_path / "gap.csv", Xg, yg)
    assert main(["evaluate", str(model), str(gap), "--json", "--no-timing"]) == 0
    out = capsys.readouterr()
    tick = json.loads(out.out)["models"][0]["tick"]
    assert tick["off_data"] == 300 and tick["inputs_held"] == 300
    assert "100.0 % of the points lie outside the training data jointly" in out.err


def test_a_fit_worse_than_a_constant_is_refused(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    assert poor_fit({"train": {"nrmse_fit_pct": 40.0}, "validation": {"nrmse_fit_pct": -3.0}})
    assert poor_fit({"train": {"nrmse_fit_pct": 40.0}, "validation": {"nrmse_fit_pct": 2.0}}
                    ) is None
    assert poor_fit({"train": {"nrmse_fit_pct": 0.0}})  # no validation set: training
    # a pressure that the inputs do not determine (noise): no model beats the mean
    rng = np.random.default_rng(3)
    X = np.c_[rng.uniform(100, 700, 400), rng.uniform(0.0, 0.2, 400)]
    table = write_table(tmp_path / "noise.csv", X, rng.uniform(0, 6, 400))
    out = tmp_path / "noise.json"
    args = ["train", str(table), "--out", str(out), "--inputs", "force_n,contraction",
            "--mfs", "3", "--block-s", "40", "--quiet"]
    assert main(args) == 5
    assert "not written: NRMSE fit" in capsys.readouterr().err and not out.exists()
    assert main([*args, "--allow-poor-fit"]) == 0
    assert "WARNING" in capsys.readouterr().err and out.exists()

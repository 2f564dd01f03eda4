"""Forward force models (seed 002, issue 28 item 2): `pamd train --target force_n --inputs
pressure_bar,contraction` on a map, judged on held-out pressure curves by `pamd evaluate
--held-out --json` with seed 002's figures; an exact polynomial recovered; bad tables and
options that do not apply refused."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pamd
from pamd.client.cli.main import main
from pamd.client.training_tables import load_samples
from pamd.models.contract import ModelEnvelope
from pamd.models.data.samples import ExtractOptions
from pamd.models.data.splitting import split
from pamd.models.registry import load_model
from pamd.models.static_force import PolynomialModel
from pamd.wire.errors import ModelError

DATA = Path(pamd.__file__).parent / "data"
CO = {"a1": 0.31, "a2": -21.0, "a3": 262.0, "a4": -40.0}  # F = p (a1 h^2 + a2 h + a3) + a4
PRESSURES = np.arange(0.0, 6.5, 0.5)  # 13 curves
CONTRACTIONS = np.linspace(-0.04, 0.25, 12)
FORWARD = ["--target", "force_n", "--inputs", "pressure_bar,contraction"]


def exact_map(path: Path) -> Path:
    """A map made by seed 002's polynomial with known coefficients (h in %)."""
    P, X = np.meshgrid(PRESSURES, CONTRACTIONS, indexing="ij")
    h = 100.0 * X
    F = P * (CO["a1"] * h ** 2 + CO["a2"] * h + CO["a3"]) + CO["a4"]
    rows = [f"{p:g},{x:.17g},{f:.17g}" for p, x, f in zip(P.ravel(), X.ravel(), F.ravel(),
                                                       strict=True)]
    path.write_text("pressure_bar,contraction,force_n\n" + "\n".join(rows) + "\n")
    return path


def test_the_exact_polynomial_is_recovered_and_judged_on_held_out_curves(
        tmp_path: Path, capsys: Any) -> None:
    table = exact_map(tmp_path / "exact.csv")
    out = tmp_path / "poly.json"
    assert main(["train", str(table), "--out", str(out), "--kind", "polynomial", *FORWARD,
                 "--split-by", "curve", "--val-split", "0", "--test-split", "0.25",
                 "--quiet"]) == 0
    model = load_model(out)
    assert isinstance(model, PolynomialModel) and model.is_forward
    assert model.output.name == "force_n" and model.n_params == 4
    for name, want in CO.items():
        assert model.coefficients[name] == pytest.approx(want, rel=1e-7, abs=1e-6), name
    held = model.provenance["split"]["test_curves_bar"]
    assert len(held) == 3  # 25 % of 13 curves, never the lowest or highest
    assert 0.0 not in held and 6.0 not in held
    capsys.readouterr()
    assert main(["evaluate", str(out), str(table), "--held-out", "test", "--json",
                 "--no-timing"]) == 0
    doc = json.loads(capsys.readouterr().out)
    m = doc["models"][0]
    assert m["n_params"] == 4 and m["tick"]["samples"] == 3 * CONTRACTIONS.size
    assert m["tick"]["offline"] is True  # the tick runs inverse models only
    assert m["metrics"]["nrmse_fit_pct"] == pytest.approx(100.0, abs=1e-4)
    assert m["metrics"]["sse"] < 1e-6
    for key in ("sse", "nrmse_fit_pct", "aic", "sbc"):
        assert key in m["metrics"]
    # the forward model's own evaluator agrees with the batch path
    ev = model.compile()
    assert ev.evaluate(3.0, 0.1) == pytest.approx(float(model.predict([[3.0, 0.1]])[0]))
    assert ev.evaluate(9.0, 0.1) == pytest.approx(float(model.predict([[6.0, 0.1]])[0]))
    assert ev.clipped and ev.clipped_mask == 1
    # a forward model never drives a muscle: the tick checks say why
    assert any("not 'pressure_bar'" in p for p in model.problems(ModelEnvelope(200, .25, .04)))


def test_sarosi_fits_the_forward_map_too(tmp_path: Path) -> None:
    out = tmp_path / "sarosi.json"
    assert main(["train", str(DATA / "dmsp20_force_map.csv"), "--out", str(out), "--kind",
                 "sarosi", *FORWARD, "--split-by", "curve", "--quiet"]) == 0
    m = load_model(out)
    # the reference's own smooth fit of this form: RMS 6.5 N over the 58 points
    assert m.metrics["train"]["rmse"] < 10.0 and m.output.name == "force_n"


def test_curves_split_holds_out_whole_interior_curves() -> None:
    s = load_samples([str(DATA / "dmsp40_force_map.csv")],
                     ExtractOptions(inputs=("pressure_bar", "contraction"), output="force_n"))
    for seed in range(6):
        parts = split(s, 0.2, 0.2, by="curve", seed=seed)
        assert parts.validation is not None and parts.test is not None
        held = parts.how["validation_curves_bar"] + parts.how["test_curves_bar"]
        assert len(held) == 2 and 0.0 not in held and 6.0 not in held
        trained = set(parts.train.X[:, 0].tolist())
        assert not trained & set(held) and {0.0, 6.0} <= trained
    with pytest.raises(ModelError, match="too few"):
        split(s, 0.5, 0.3, by="curve")  # 6 of 7 curves: the two ends must train


def test_the_packaged_datasheet_maps() -> None:
    """DMSP-20 and DMSP-40 (seed 002 compares both): seven curves, 0-6 bar; the DMSP-40
    pulls 6000 N at 6 bar near 0 % contraction, as its datasheet says."""
    for name, lo in (("dmsp20_force_map.csv", -0.04), ("dmsp40_force_map.csv", -0.05)):
        rows = np.loadtxt(DATA / name, delimiter=",", skiprows=1)
        assert sorted(set(rows[:, 0].tolist())) == [0, 1, 2, 3, 4, 5, 6]
        assert rows[:, 1].min() == lo and rows[:, 1].max() == 0.25
    d40 = np.loadtxt(DATA / "dmsp40_force_map.csv", delimiter=",", skiprows=1)
    assert [6.0, 0.006, 6000.0] in d40.tolist()


@pytest.mark.parametrize("args, message", [
    (["--kind", "polynomial", "--kernel", "cubic"], "--kernel is an option of svr, not of "
                                                    "--kind polynomial"),
    (["--kind", "svr", "--solver", "lm"], "--solver is an option of mlp, not of --kind svr"),
    (["--kind", "mlp", "--hidden", "0"], "--hidden must be at least 1"),
    (["--kind", "polynomial", "--target", "length_mm"], "a polynomial model predicts "
                                                        "pressure_bar or force_n"),
    (["--kind", "polynomial", "--target", "pressure_bar", "--inputs",
      "pressure_bar,contraction"], "cannot be both an input and the output"),
    (["--kind", "polynomial", "--target", "force_n", "--inputs", "force_n,contraction"],
     "cannot be both an input and the output"),
    (["--kind", "polynomial", "--target", "force_n", "--inputs", "pressure_bar,length_mm"],
     "takes the inputs force_n,contraction"),
    (["--kind", "polynomial", "--target", "length_mm", "--inputs", "force_n,contraction"],
     "predicts pressure_bar or force_n"),
    (["--kind", "mlp", "--target", "force_n", "--inputs", "contraction", "--split-by",
      "curve"], "pressure_bar must be an input or the target"),
])
def test_options_that_do_not_apply_are_refused(args: list[str], message: str,
                                               tmp_path: Path, capsys: Any) -> None:
    out = tmp_path / "x.json"
    capsys.readouterr()
    assert main(["train", str(DATA / "dmsp20_force_map.csv"), "--out", str(out),
                 "--quiet", *args]) == 5
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_a_model_without_held_out_curves_is_refused_for_held_out(tmp_path: Path,
                                                                 capsys: Any) -> None:
    out = tmp_path / "p.json"
    table = str(DATA / "dmsp20_force_map.csv")
    assert main(["train", table, "--out", str(out), "--kind", "polynomial", *FORWARD,
                 "--block-s", "8", "--quiet"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(out), table, "--held-out", "test", "--no-timing"]) == 5
    assert "held out no test part (train it with --test-split above 0)" in \
        capsys.readouterr().err


@pytest.mark.parametrize("header, row, where", [
    ("pressure [bar],contraction [%],force [lbs]", "2,5,100", ":1:force [lbs]: unknown "
                                                             "unit 'lbs' for force"),
    ("pressure_bar,contraction,force_n", "2,0.05,nan", ":4:force_n: nan in a sample"),
    ("pressure_bar,contraction,force_n", "2,0.05,12x", ":4:force_n: '12x' is not a number"),
    ("pressure_bar,force_n", "2,100", ":1: missing column(s) contraction"),
])
def test_bad_maps_are_refused_naming_row_and_column(header: str, row: str, where: str,
                                                    tmp_path: Path, capsys: Any) -> None:
    grid = [(p, x) for p in range(7) for x in np.arange(0.0, 0.25, 0.02)]  # 91 rows
    rows = [f"{p},{x:g},{100 * p - x:g}" if header.count(",") == 2 else f"{p},{100 * p}"
            for p, x in grid]
    table = tmp_path / "map.csv"
    table.write_text("\n".join([header, *rows[:2], row, *rows[2:]]) + "\n")
    capsys.readouterr()
    assert main(["train", str(table), "--out", str(tmp_path / "m.json"), "--kind",
                 "polynomial", *FORWARD, "--quiet"]) == 5
    assert f"{table}{where}" in capsys.readouterr().err


def test_seed_002_figures_as_the_readme_reports() -> None:
    """bench/seed002.py's protocol (leave-one-curve-out over 1-5 bar, the kinds' defaults,
    seed 0) gives the docs' figures for the polynomial, the best MLP and the cubic and
    fine-Gaussian SVMs (deterministic: no clock, no load dependence)."""
    bench = Path(__file__).resolve().parents[2] / "bench"
    sys.path.insert(0, str(bench))
    try:
        import seed002  # type: ignore[import-not-found]
    finally:
        sys.path.remove(str(bench))
    want = {"DMSP-20": {"polynomial": 67.77, "mlp 5": 98.62, "svr cubic": 89.73,
                        "svr fine-gaussian": 13.26},
            "DMSP-40": {"polynomial": 75.03, "svr cubic": 90.91}}
    models = seed002.models(quick=False)
    for muscle, figures in want.items():
        samples = load_samples([str(DATA / seed002.MAPS[muscle])], seed002.OPTS,
                               report=lambda _line: None)
        for label, fit in figures.items():
            kind, options = models[label]
            m = seed002.judge_held_out_curves(samples, kind, options)
            assert m["nrmse_fit_pct"] == pytest.approx(fit, abs=0.01), (muscle, label)

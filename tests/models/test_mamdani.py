"""Seed 001's Mamdani model: the centroid evaluated exactly (a hand-built rule base
against an independent computation and a case with a closed-form answer), a known rule
base read back off the data it made, the tick evaluator equal to the batch one, files,
bad files, and `pamd train --kind mamdani` end to end."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pamd.client.cli.main import main
from pamd.models.contract import ModelEnvelope, Variable
from pamd.models.data.extraction import derived_inputs
from pamd.models.mamdani import (
    DEFUZZ_POINTS,
    MamdaniModel,
    MamdaniOptions,
    fit_mamdani,
    rule_base,
)
from pamd.models.registry import KINDS, dumps_model, load_model
from pamd.wire.errors import ModelError

NAMES = ["force_n", "length_mm", "velocity_mm_s"]
UNITS = ["N", "mm", "mm/s"]


def one_input(rules: list[int]) -> MamdaniModel:
    """x in [0, 10] N with Low/Medium/High; pressure 0-4 bar with 3 output sets."""
    return MamdaniModel([Variable("force_n", "N", 0.0, 10.0)],
                        Variable("pressure_bar", "bar", 0.0, 4.0),
                        centres=[[0.0, 0.5, 1.0]], widths=[[0.2, 0.2, 0.2]],
                        out_centres=[1.0, 2.0, 3.0], out_widths=[0.3, 0.3, 0.3],
                        rules=rules)


def by_hand(model: MamdaniModel, x: float) -> float:
    """The definition, written out: product firing, min implication, max aggregation,
    centroid over 101 points of the output range."""
    s = (x - model.inputs[0].min) / (model.inputs[0].max - model.inputs[0].min)
    w = [math.exp(-(s - c) ** 2 / (2 * 0.2 ** 2)) for c in (0.0, 0.5, 1.0)]
    num = den = 0.0
    for k in range(DEFUZZ_POINTS):
        yk = 4.0 * k / (DEFUZZ_POINTS - 1)
        mu = max(min(w[r], math.exp(-(yk - model.out_centres[j]) ** 2 / (2 * 0.3 ** 2)))
                 for r, j in enumerate(model.rules.tolist()))
        num += mu * yk
        den += mu
    return num / den


def test_centroid_is_the_definition_exactly() -> None:
    model = one_input([0, 2, 1])
    xs = np.array([0.0, 1.7, 5.0, 7.3, 10.0])
    got = model.predict(xs[:, None])
    np.testing.assert_allclose(got, [by_hand(model, x) for x in xs], rtol=1e-12)
    c = model.compile()
    for x, want in zip(xs, got, strict=True):
        assert c.evaluate(float(x)) == pytest.approx(want, rel=1e-12)
    # A symmetric case has a closed-form answer: at x = 5 N only the Medium rule fires
    # fully and Low/High fire alike on sets placed symmetrically about 2 bar, so the
    # joined set is symmetric about 2 bar (the grid too): the centroid is 2 bar.
    sym = one_input([0, 1, 2])
    assert sym.predict(np.array([[5.0]]))[0] == pytest.approx(2.0, abs=1e-12)


def test_inputs_are_held_to_their_range_and_counted() -> None:
    model = one_input([0, 1, 2])
    y, clipped = model.predict(np.array([[-5.0], [15.0], [3.0]]), return_clipped=True)
    assert clipped.tolist() == [True, True, False]
    assert y[0] == pytest.approx(model.predict(np.array([[0.0]]))[0])
    c = model.compile()
    c.evaluate(15.0)
    assert c.clipped and c.clipped_mask == 1


def test_the_tick_evaluator_is_the_batch_one_on_three_inputs() -> None:
    """The tick's evaluator (built in place, each grid point's sets walked in order of
    membership and left at the first that cannot raise the value) against the batch
    centroid, which compares every set at every point: inside, outside and on the
    edges of the ranges, with narrow sets that leave points with one set, and where
    every rule underflows (the strongest rule's set centre, rule 0 on a tie)."""
    rng = np.random.default_rng(7)
    inputs = [Variable(n, u, 0.0, 1.0) for n, u in zip(NAMES, UNITS, strict=True)]
    for out_width, in_width in ((0.3, 0.2), (0.05, 0.2), (1.5, 0.05)):
        model = MamdaniModel(inputs, Variable("pressure_bar", "bar", 0.0, 6.0),
                             centres=[[0.0, 0.5, 1.0], [0.1, 0.9], [0.0, 0.3, 0.6, 1.0]],
                             widths=[[in_width] * 3, [in_width] * 2, [in_width] * 4],
                             out_centres=[0.5, 2.0, 3.0, 4.5, 5.5],
                             out_widths=[out_width] * 5, rules=rng.integers(0, 5, 24))
        X = np.r_[rng.uniform(-0.2, 1.2, (300, 3)), [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]]
        c = model.compile()
        got = [c.evaluate(*x) for x in X.tolist()]
        np.testing.assert_allclose(got, model.predict(X), rtol=1e-12, atol=1e-12)
    narrow = MamdaniModel(inputs, Variable("pressure_bar", "bar", 0.0, 6.0),
                          centres=[[0.0, 1.0]] * 3, widths=[[0.001] * 2] * 3,
                          out_centres=[1.0, 5.0], out_widths=[0.3, 0.3],
                          rules=[1, 0, 0, 0, 0, 0, 0, 0])
    far = np.array([[0.5, 0.5, 0.5]])  # every membership underflows to 0
    assert narrow.predict(far)[0] == 5.0 == narrow.compile().evaluate(0.5, 0.5, 0.5)


def test_a_known_rule_base_is_read_back_off_its_data() -> None:
    rng = np.random.default_rng(0)
    truth_rules = rng.integers(0, 5, 27)
    inputs = [Variable(n, u, 0.0, 1.0) for n, u in zip(NAMES, UNITS, strict=True)]
    truth = MamdaniModel(inputs, Variable("pressure_bar", "bar", 0.0, 6.0),
                         centres=[[0.0, 0.5, 1.0]] * 3, widths=[[0.12] * 3] * 3,
                         out_centres=np.linspace(1.0, 5.0, 5), out_widths=[0.3] * 5,
                         rules=truth_rules)
    X = rng.uniform(0.0, 1.0, (3000, 3))
    y = truth.predict(X)
    got = rule_base(truth.firing(X), y, truth.out_centres, truth.out_widths)
    np.testing.assert_array_equal(got, truth_rules)


def test_fit_tunes_the_memberships_and_round_trips(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    X = np.c_[rng.uniform(100, 800, 400), rng.uniform(160, 205, 400), rng.uniform(-3, 3, 400)]
    y = X[:, 0] / 250.0 + (200.0 - X[:, 1]) / 12.0 + 0.2 * np.tanh(X[:, 2])
    plain = fit_mamdani(X, y, MamdaniOptions(tune="none"), input_names=NAMES,
                        input_units=UNITS)
    tuned = fit_mamdani(X, y, MamdaniOptions(tune="mga", generations=6, population=16),
                        input_names=NAMES, input_units=UNITS,
                        derived_inputs=derived_inputs(tuple(NAMES), 3.0))
    assert plain.n_params == 28 and plain.n_rules == 27
    np.testing.assert_array_equal(plain.rules, tuned.rules)  # the rule base is not tuned
    assert tuned.metrics["train"]["mse"] < plain.metrics["train"]["mse"]
    assert tuned.provenance["tuning"]["best_mse"] <= tuned.provenance["tuning"]["initial_mse"]
    back = load_model(dumps_model(tuned).encode())
    assert isinstance(back, MamdaniModel) and back.kind == "mamdani"
    np.testing.assert_allclose(back.predict(X), tuned.predict(X), rtol=1e-12)
    assert back.problems(ModelEnvelope(200.0, 0.25, 0.05)) == []  # it can drive a muscle
    assert "state its filter" in plain.problems(ModelEnvelope(200.0, 0.25, 0.05))[0]


def test_bad_files_are_refused_naming_the_field() -> None:
    doc: dict[str, Any] = json.loads(dumps_model(one_input([0, 2, 1])))
    doc["parameters"]["rules"][1]["then"] = 7
    with pytest.raises(ModelError, match="output MF indices in 0..2"):
        load_model(doc)
    doc["parameters"]["rules"][1] = {"mfs": [2], "then": 1}
    with pytest.raises(ModelError, match=r"rules\[1\].mfs: expected \[1\]"):
        load_model(doc)
    doc["parameters"]["output_mfs"]["widths"] = [0.3, -0.3, 0.3]
    doc["parameters"]["rules"][1] = {"mfs": [1], "then": 1}
    with pytest.raises(ModelError, match="positive widths"):
        load_model(doc)


def test_train_and_evaluate_a_mamdani_model(sweeps: list[Path], tmp_path: Path,
                                            capsys: Any) -> None:
    assert "mamdani" in KINDS
    out = tmp_path / "mam.json"
    runs = [str(p) for p in sweeps]
    assert main(["train", *runs, "--out", str(out), "--kind", "mamdani", "--tune", "none",
                 "--quiet", "--block-s", "2", "--allow-poor-fit"]) == 0
    model = load_model(out)
    assert model.kind == "mamdani" and [v.name for v in model.inputs] == NAMES
    capsys.readouterr()
    assert main(["evaluate", str(out), str(sweeps[1]), "--json", "--no-timing"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["models"][0]["n_params"] == 28 and 0 < doc["rmse"] < 2.0
    # another kind's option, and an option that does not apply, are refused
    assert main(["train", *runs, "--out", str(out), "--kind", "mamdani", "--tuner", "ga",
                 "--quiet"]) != 0
    assert main(["train", *runs, "--out", str(out), "--kind", "mamdani", "--tune", "none",
                 "--epochs", "5", "--quiet"]) != 0

"""Constant rule consequents (zero-order Sugeno, `consequent="constant"`, `pamd train
--consequent constant`): f = q per rule, the p held at 0 by training, files, the tick's
evaluator and online adaptation alike; R consequent parameters instead of R (d + 1)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.client.cli.main import main  # noqa: E402
from pamd.models.anfis import TrainingOptions, dumps, fit, load, loads, train  # noqa: E402
from pamd.models.anfis.adapted import adapted_model  # noqa: E402
from pamd.models.anfis.model import AnfisModel, init_model  # noqa: E402
from pamd.models.anfis.rls import OutputBound  # noqa: E402
from pamd.wire.errors import ModelError  # noqa: E402


def zero_order(model: AnfisModel, q: np.ndarray) -> AnfisModel:
    """`model` made zero order with rule constants q."""
    cons = np.zeros_like(model.consequents)
    cons[:, -1] = q
    twin = model.copy()
    twin.consequent, twin.consequents = "constant", cons
    return twin


def test_least_squares_recovers_known_rule_constants(model_factory) -> None:
    # Data made by a zero-order model: one epoch (premises untouched, consequents by
    # least squares) gives its constants back.
    truth = zero_order(model_factory("gaussian", (3, 4), seed=1),
                       np.random.default_rng(5).uniform(-2.0, 2.0, 12))
    X = np.random.default_rng(6).uniform(0.0, 1.0, (400, 2))
    start = zero_order(truth, np.zeros(12))
    result = train(start, X, truth.predict(X), TrainingOptions(epochs=1))
    np.testing.assert_allclose(result.model.consequents, truth.consequents, atol=1e-9)
    assert result.model.n_consequent_params == 12
    assert result.model.n_params == 12 + 2 * 7


def test_constant_consequents_are_constants_where_linear_ones_are_not() -> None:
    # One MF per input is one rule: linear fits y = 2 x1 - x2 + 1 exactly, a constant
    # rule can only give the mean.
    X = np.random.default_rng(0).uniform(0.0, 1.0, (200, 2))
    y = 2 * X[:, 0] - X[:, 1] + 1
    lin = fit(X, y, TrainingOptions(n_mfs=1, epochs=3)).model
    const = fit(X, y, TrainingOptions(n_mfs=1, epochs=3, consequent="constant")).model
    assert np.abs(lin.predict(X) - y).max() < 1e-9
    np.testing.assert_allclose(const.predict(X), y.mean(), rtol=1e-9)
    assert np.all(const.consequents[:, :-1] == 0.0)
    assert (lin.n_params, const.n_params) == (3 + 4, 1 + 4)
    assert const.provenance["training"]["options"]["consequent"] == "constant"


def test_a_zero_order_model_learns_a_smooth_surface() -> None:
    # More rules make up for the constants: 6 x 6 constant rules on a smooth surface.
    rng = np.random.default_rng(2)
    X = rng.uniform(-1.0, 1.0, (600, 2))
    f = lambda X: np.tanh(2 * X[:, 0]) * np.cos(1.5 * X[:, 1])  # noqa: E731
    result = fit(X, f(X), TrainingOptions(n_mfs=6, epochs=60, consequent="constant"))
    X_test = rng.uniform(-0.95, 0.95, (500, 2))
    err = result.model.predict(X_test) - f(X_test)
    assert float(np.sqrt(np.mean(err ** 2))) < 0.03
    assert result.train_rmse.min() < 0.8 * result.train_rmse[0]  # the premises learn too


def test_the_file_says_constant_and_reads_back_bit_for_bit(model_factory) -> None:
    model = zero_order(model_factory("gaussian", (3, 3), seed=2), np.linspace(-1, 1, 9))
    text = dumps(model)
    doc = json.loads(text)
    assert doc["consequent"] == "constant"
    assert all(set(rule) == {"mfs", "q"} for rule in doc["rules"])
    back = loads(text)
    assert back.consequent == "constant" and back.n_params == model.n_params
    X = np.random.default_rng(1).uniform(0.0, 1.0, (50, 2))
    assert np.array_equal(back.predict(X), model.predict(X))
    linear = json.loads(dumps(model_factory("gaussian", (3, 3), seed=2)))
    assert "consequent" not in linear and all("p" in r for r in linear["rules"])
    doc["rules"][0]["p"] = [0.0, 0.0]  # p = 0 written out is read as well
    assert np.array_equal(loads(json.dumps(doc)).consequents, model.consequents)


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d["rules"][4].update(p=[0.5, 0.0]), r"rules\[4\]\.p: a model with constant"),
    (lambda d: d.update(consequent="quadratic"), "field consequent: 'quadratic' is not one"),
])
def test_bad_constant_files_are_refused(model_factory, edit: Any, message: str) -> None:
    doc = json.loads(dumps(zero_order(model_factory("gaussian", (3, 3), seed=2),
                                      np.ones(9))))
    edit(doc)
    with pytest.raises(ModelError, match=message):
        loads(json.dumps(doc), source="m.json")


def test_a_constant_model_with_slopes_p_is_refused(model_factory) -> None:
    model = model_factory("gaussian", (2, 2), seed=0)
    with pytest.raises(ModelError, match="every rule's p must be 0"):
        AnfisModel(model.inputs, model.output, mf_type="gaussian", scaling="minmax",
                   scale_offset=model.scale_offset, scale_span=model.scale_span,
                   centres=model.centres, widths=model.widths,
                   consequents=model.consequents, consequent="constant")


def test_the_tick_evaluator_and_adaptation_see_only_the_constants(model_factory) -> None:
    model = zero_order(model_factory("gaussian", (3, 3, 3), seed=4),
                       np.random.default_rng(0).uniform(0, 5, 27))
    ff = model.compile()
    assert ff.n_consequents == 27
    X = np.random.default_rng(3).uniform(-0.1, 1.1, (40, 3))
    got = [ff.evaluate(*x) for x in X.tolist()]
    np.testing.assert_allclose(got, model.predict(X), rtol=1e-12)
    ff.evaluate(0.3, 0.6, 0.2)
    wbar = model.firing_strengths(model.scale(np.array([[0.3, 0.6, 0.2]])))[0]
    np.testing.assert_allclose(ff.regressor(), wbar, rtol=1e-12)  # phi = wbar
    theta = ff.theta(np.empty(27)) + 0.5
    ff.set_consequents(theta)
    assert ff.evaluate(0.3, 0.6, 0.2) == pytest.approx(float(wbar @ theta), rel=1e-12)
    assert all(v == 0.0 for col in ff.consequent_columns[:-1] for v in col)  # p stay 0
    bound = OutputBound.for_model(model)
    assert bound.phi_grid.shape[1] == 27
    assert bound.bar(np.full(27, 0.25)) == pytest.approx(0.25)  # sum of wbar is 1
    adapted = adapted_model(model.copy(), {"consequents": theta.tolist()})
    assert adapted.consequent == "constant"
    np.testing.assert_allclose(adapted.consequents[:, -1], theta)
    with pytest.raises(ModelError, match="expected 27 finite values"):
        adapted_model(model.copy(), {"consequents": np.zeros(4 * 27).tolist()})


def test_init_model_lays_out_a_constant_model() -> None:
    X = np.random.default_rng(0).uniform(0, 1, (30, 2))
    m = init_model(X, X[:, 0], n_mfs=2, consequent="constant")
    assert m.consequent == "constant" and m.n_consequent_params == 4
    with pytest.raises(ModelError, match="unknown rule consequent"):
        init_model(X, X[:, 0], n_mfs=2, consequent="cubic")
    with pytest.raises(ValueError, match="consequent"):
        fit(X, X[:, 0], TrainingOptions(n_mfs=2, consequent="cubic"))


def test_pamd_train_consequent_constant(recording: Path, tmp_path: Path, capsys: Any) -> None:
    out = tmp_path / "c.json"
    assert main(["train", str(recording), "--out", str(out), "--kind", "anfis",
                 "--inputs", "force_n,length_mm", "--consequent", "constant", "--mfs", "3",
                 "--epochs", "5",
                 "--block-s", "1", "--settle-s", "0.5", "--quiet"]) == 0
    model = load(out)
    assert model.consequent == "constant" and np.all(model.consequents[:, :-1] == 0.0)
    assert model.n_params == 9 + 2 * 6
    capsys.readouterr()
    assert main(["evaluate", str(out), str(recording), "--json"]) == 0
    [entry] = json.loads(capsys.readouterr().out)["models"]
    assert entry["n_params"] == 21
    default = tmp_path / "l.json"
    assert main(["train", str(recording), "--out", str(default), "--mfs", "3", "--epochs",
                 "2", "--block-s", "1", "--settle-s", "0.5", "--quiet"]) == 0
    assert load(default).consequent == "linear"  # seed 000's first-order model


def test_consequent_is_refused_where_it_does_not_apply(recording: Path, tmp_path: Path,
                                                       capsys: Any) -> None:
    code = main(["train", str(recording), "--out", str(tmp_path / "x.json"), "--kind",
                 "polynomial", "--consequent", "constant", "--quiet"])
    assert code == 5
    assert "--consequent is an option of" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: not one of the choices
        main(["train", str(recording), "--out", str(tmp_path / "x.json"),
              "--consequent", "cubic", "--quiet"])
    assert "invalid choice: 'cubic'" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()

"""Seed 001's TS fuzzy model: 27 singletons (45 parameters) by default, recovered exactly
from data a known singleton model made; first order on request; the paper's GA (roulette
wheel on F = 1/(1+MSE) itself) and the MGA (elitism, gradient-based selection); runs
repeat with the seed; files load and say what they are."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pamd.models.anfis.adapted import adapted_model
from pamd.models.anfis.model import AnfisModel, init_model
from pamd.models.genetic import GaOptions, _roulette, decode, encode, minimise
from pamd.models.registry import dumps_model, load_model, save_model
from pamd.models.ts_fuzzy import (
    TsFuzzyOptions,
    _finish,
    fit_ts_fuzzy,
    premise_cost,
)
from pamd.wire.errors import ModelError

NAMES = ["force_n", "length_mm", "velocity_mm_s"]
UNITS = ["N", "mm", "mm/s"]


def data(n: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A smooth inverse-like map with a velocity-dependent branch (hysteresis-like)."""
    rng = np.random.default_rng(seed)
    F = rng.uniform(100, 800, n)
    ln = rng.uniform(160, 205, n)
    v = rng.uniform(-3, 3, n)
    p = F / 250.0 + (200.0 - ln) / 12.0 + 0.3 * np.tanh(v) + 0.2 * np.sin(F / 150.0)
    return np.c_[F, ln, v], p


def known_singleton(n: int = 400) -> tuple[AnfisModel, np.ndarray, np.ndarray]:
    """A singleton TS model with moved premises and set singletons, and data it made."""
    X, y = data(n)
    truth = init_model(X, y, n_mfs=3, input_names=NAMES, input_units=UNITS,
                       output_name="pressure_bar", output_unit="bar", consequent="constant")
    vec = truth.premise_vector()
    vec[:9] += np.linspace(-0.1, 0.1, 9)  # centres off the grid
    vec[9:] *= np.linspace(0.8, 1.3, 9)  # widths too
    truth.set_premise_vector(vec)
    truth.consequents[:, -1] = np.linspace(0.5, 6.0, 27) ** 1.5 / 4.0
    truth.kind = "ts-fuzzy"
    return truth, X, truth.predict(X)


def test_singletons_are_recovered_exactly_and_counted_as_the_paper() -> None:
    truth, X, y = known_singleton()
    assert truth.n_params == 45 and truth.n_rules == 27  # seed 001: 18 + 27
    assert premise_cost(truth, X, y)(truth.premise_vector()) < 1e-20
    fitted = truth.copy()
    fitted.consequents[:] = 0.0
    _finish(fitted, truth.premise_vector(), X, y)  # the SVD least squares of the paper
    np.testing.assert_allclose(fitted.consequents, truth.consequents, atol=1e-8)
    assert not np.any(fitted.consequents[:, :-1])  # singletons: no slopes


def test_first_order_on_request_has_126_parameters() -> None:
    X, y = data()
    lin, _ = fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner="gd", consequent="linear", epochs=3),
                          input_names=NAMES, input_units=UNITS)
    const, _ = fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner="gd", epochs=3), input_names=NAMES,
                            input_units=UNITS)
    assert lin.n_params == 126 and np.any(lin.consequents[:, :-1])
    assert const.n_params == 45 and const.consequent == "constant"
    assert "consequent" not in lin.to_dict() and const.to_dict()["consequent"] == "constant"
    assert const.describe()["consequent"] == "constant" and const.describe()["n_params"] == 45


def test_singleton_gd_descends_and_keeps_the_best_epoch() -> None:
    truth, X, y = known_singleton()
    model, hist = fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner="gd", epochs=30), input_names=NAMES,
                               input_units=UNITS)
    assert hist.size == 30 and hist[-1] < 0.5 * hist[0]
    best = model.provenance["tuning"]["best_epoch"]
    assert model.metrics["train"]["mse"] == pytest.approx(hist[best - 1], rel=1e-6)


def test_roulette_is_proportional_to_the_fitness_itself() -> None:
    costs = np.array([0.0, 1.0, 3.0])  # F = 1, 1/2, 1/4
    rng = np.random.default_rng(0)
    picks = np.bincount(_roulette(costs, rng, 70000), minlength=3) / 70000
    np.testing.assert_allclose(picks, np.array([4, 2, 1]) / 7, atol=0.01)
    scaled = np.bincount(_roulette(costs, rng, 70000, "linear"), minlength=3) / 70000
    np.testing.assert_allclose(scaled, np.array([0.75, 0.25, 0.0]), atol=0.01)


def test_encoding_round_trips_to_12_bits() -> None:
    lo, hi = np.array([0.0, -1.0]), np.array([1.0, 1.0])
    x = np.array([[0.25, 0.5], [1.0, -1.0]])
    back = decode(encode(x, lo, hi), lo, hi)
    assert np.abs(back - x).max() <= (hi - lo).max() / 4095 / 2 + 1e-12


@pytest.mark.parametrize(("modified", "scaling"), [(False, "linear"), (True, "none"),
                                                   (True, "linear")])
def test_ga_improves_on_its_initial_population(modified: bool, scaling: str) -> None:
    def cost(p: np.ndarray) -> float:  # a bowl, minimum 0 at (0.3, 0.7)
        return float((p[0] - 0.3) ** 2 + 5 * (p[1] - 0.7) ** 2)

    lo, hi = np.zeros(2), np.ones(2)
    res = minimise(cost, lo, hi, GaOptions(population=40, generations=30, seed=3,
                                           modified=modified, scaling=scaling))
    assert res.best_cost < 0.2 * res.history[0]
    assert res.best_cost == pytest.approx(cost(res.best))
    if modified:  # elitism: every generation holds the best string found so far
        np.testing.assert_array_equal(res.population_best, res.history)
        assert res.switched_at is not None  # and it switched to gradient-based selection


def test_unknown_scaling_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown fitness scaling 'rank'"):
        minimise(lambda p: 0.0, np.zeros(1), np.ones(1), GaOptions(scaling="rank"))


@pytest.mark.parametrize("tuner", ["ga", "mga"])
def test_ts_fuzzy_ga_and_mga_repeat_and_load(tuner: str, tmp_path: Path) -> None:
    X, y = data()
    opts = TsFuzzyOptions(tuner=tuner, epochs=8, population=20, seed=1)
    model, hist = fit_ts_fuzzy(X, y, opts, input_names=NAMES, input_units=UNITS,
                               validation=data(100, 5))
    assert model.kind == "ts-fuzzy" and model.n_rules == 27 and model.n_params == 45
    assert np.all(np.diff(hist) <= 0)  # the best so far never gets worse
    tuning = model.provenance["tuning"]
    assert tuning["fitness_rows"] == y.size and tuning["ridge"] == 0.0  # seed 001
    assert tuning["options"]["scaling"] == "none" and tuning["grid_start"] is False
    assert model.metrics["train"]["mse"] == pytest.approx(hist[-1], rel=1e-6)
    if tuner == "mga":
        assert hist[-1] < hist[0]
    again, hist2 = fit_ts_fuzzy(X, y, opts, input_names=NAMES, input_units=UNITS,
                                validation=data(100, 5))
    np.testing.assert_array_equal(hist, hist2)  # seeded: the run repeats
    back = load_model(save_model(model, tmp_path / "tsf.json"))
    assert back.kind == "ts-fuzzy" and back.n_params == 45
    np.testing.assert_allclose(back.predict(X[:20]), model.predict(X[:20]), rtol=1e-12)
    c = back.compile()
    assert c.evaluate(*X[3]) == pytest.approx(float(model.predict(X[3:4])[0]), rel=1e-12)


def test_a_constant_file_with_slopes_is_refused() -> None:
    truth, _, _ = known_singleton()
    doc = json.loads(dumps_model(truth))
    doc["rules"][4]["p"] = [0.0, 0.1, 0.0]
    with pytest.raises(ModelError, match=r"rules\[4\]\.p: .*p = 0"):
        load_model(doc)
    doc["consequent"] = "quadratic"
    with pytest.raises(ModelError, match="consequent: 'quadratic'"):
        load_model(doc)


def test_unknown_tuner_and_consequent_are_refused() -> None:
    X, y = data()
    with pytest.raises(ModelError, match="unknown tuner 'pso'"):
        fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner="pso"), input_names=NAMES, input_units=UNITS)
    with pytest.raises(ModelError, match="unknown consequent 'cubic'"):
        fit_ts_fuzzy(X, y, TsFuzzyOptions(consequent="cubic"), input_names=NAMES,
                     input_units=UNITS)


def test_a_singleton_model_adapts_its_27_constants_and_stays_singleton(tmp_path: Path) -> None:
    """One implementation of constant consequents: the singleton TS model is ANFIS's
    zero-order model, so online adaptation moves its 27 singletons alone (not 108
    first-order parameters), and the adapted file is still seed 001's 45-parameter
    model, written in the ts-fuzzy layout (p = 0 in every rule)."""
    truth, X, _ = known_singleton()
    ff = truth.compile()
    assert ff.n_consequents == 27
    theta = ff.theta(np.empty(27)) + np.linspace(0.0, 0.3, 27)
    adapted = adapted_model(truth.copy(), {"consequents": theta.tolist()})
    assert adapted.consequent == "constant" and adapted.n_params == 45
    np.testing.assert_array_equal(adapted.consequents[:, -1], theta)
    doc = json.loads(dumps_model(adapted))
    assert doc["kind"] == "ts-fuzzy" and doc["consequent"] == "constant"
    assert all(rule["p"] == [0.0, 0.0, 0.0] for rule in doc["rules"])
    back = load_model(save_model(adapted, tmp_path / "adapted.json"))
    assert back.n_params == 45 and back.describe()["consequent"] == "constant"
    np.testing.assert_array_equal(back.predict(X[:20]), adapted.predict(X[:20]))

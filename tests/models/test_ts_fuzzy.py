"""Seed 001's TS fuzzy model: GA and MGA improve on their initial population, the MGA
keeps its best and switches selection, runs repeat with the seed, files load."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pamd.errors import ModelError
from pamd.models.genetic import GaOptions, decode, encode, minimise
from pamd.models.registry import load_model, save_model
from pamd.models.ts_fuzzy import TsFuzzyOptions, fit_ts_fuzzy

NAMES = ["force_n", "length_mm", "velocity_mm_s"]


def data(n: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A smooth inverse-like map with a velocity-dependent branch (hysteresis-like)."""
    rng = np.random.default_rng(seed)
    F = rng.uniform(100, 800, n)
    ln = rng.uniform(160, 205, n)
    v = rng.uniform(-3, 3, n)
    p = F / 250.0 + (200.0 - ln) / 12.0 + 0.3 * np.tanh(v) + 0.2 * np.sin(F / 150.0)
    return np.c_[F, ln, v], p


def test_encoding_round_trips_to_12_bits() -> None:
    lo, hi = np.array([0.0, -1.0]), np.array([1.0, 1.0])
    x = np.array([[0.25, 0.5], [1.0, -1.0]])
    back = decode(encode(x, lo, hi), lo, hi)
    assert np.abs(back - x).max() <= (hi - lo).max() / 4095 / 2 + 1e-12


@pytest.mark.parametrize("modified", [False, True])
def test_ga_improves_on_its_initial_population(modified: bool) -> None:
    def cost(p: np.ndarray) -> float:  # Rosenbrock-like bowl, minimum 0 at (0.3, 0.7)
        return float((p[0] - 0.3) ** 2 + 5 * (p[1] - 0.7) ** 2)

    lo, hi = np.zeros(2), np.ones(2)
    res = minimise(cost, lo, hi, GaOptions(population=40, generations=30, seed=3,
                                           modified=modified))
    assert res.best_cost < 0.2 * res.history[0]
    assert res.best_cost == pytest.approx(cost(res.best))
    if modified:  # elitism: every generation holds the best string found so far
        np.testing.assert_array_equal(res.population_best, res.history)
        assert res.switched_at is not None  # and it switched to gradient-based selection


@pytest.mark.parametrize("tuner", ["ga", "mga"])
def test_ts_fuzzy_ga_and_mga_improve_and_repeat(tuner: str, tmp_path: Path) -> None:
    X, y = data()
    opts = TsFuzzyOptions(tuner=tuner, epochs=8, population=20, seed=1)
    model, hist = fit_ts_fuzzy(X, y, opts, input_names=NAMES, input_units=["N", "mm", "mm/s"],
                               validation=data(100, 5))
    assert model.kind == "ts-fuzzy" and model.n_rules == 27
    assert hist[-1] < hist[0]  # better than the best of the initial population
    tuning = model.provenance["tuning"]
    assert tuning["best_mse"] < tuning["initial_mse"]
    assert model.metrics["train"]["mse"] == pytest.approx(hist[-1], rel=1e-6)
    again, hist2 = fit_ts_fuzzy(X, y, opts, input_names=NAMES,
                                input_units=["N", "mm", "mm/s"], validation=data(100, 5))
    np.testing.assert_array_equal(hist, hist2)  # seeded: the run repeats
    back = load_model(save_model(model, tmp_path / "tsf.json"))
    assert back.kind == "ts-fuzzy"
    np.testing.assert_allclose(back.predict(X[:20]), model.predict(X[:20]), rtol=1e-12)


def test_gd_tuner_trains_and_unknown_tuner_is_refused() -> None:
    X, y = data()
    model, hist = fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner="gd", epochs=5), input_names=NAMES,
                               input_units=["N", "mm", "mm/s"])
    assert model.kind == "ts-fuzzy" and hist.size == 5 and model.provenance["tuning"][
        "tuner"] == "gd"
    with pytest.raises(ModelError, match="unknown tuner 'pso'"):
        fit_ts_fuzzy(X, y, TsFuzzyOptions(tuner="pso"), input_names=NAMES,
                     input_units=["N", "mm", "mm/s"])

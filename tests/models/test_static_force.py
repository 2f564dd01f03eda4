"""The static force kinds (seeds 002 and 004): known coefficients recovered, the closed
form inverse, the tick evaluator, files and refusals."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pamd.models.contract import ModelEnvelope
from pamd.models.registry import load_model, save_model
from pamd.models.static_force import PolynomialModel, fit_coefficients, fit_static
from pamd.wire.errors import ModelError

#: rig-physics.md's smooth fit of the DMSP-20 force map (d = 0): a known Sarosi model.
SAROSI = {"a": -10.1206, "b": 236.3164, "c": -0.3378, "d": 0.0, "e": -7.9242,
          "f": -1.8549, "g": 263.2552, "h": -238.7719}
POLY = {"a1": 0.21, "a2": -14.0, "a3": 250.0, "a4": -40.0}
ENV = ModelEnvelope(200.0, 0.25, 0.04)


def grid(n: int = 400, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(0.5, 6.0, n), rng.uniform(-0.02, 0.20, n)


def forward(kind: str, co: dict[str, float], p: np.ndarray, x: np.ndarray) -> np.ndarray:
    k = 100.0 * x
    if kind == "polynomial":
        return p * (co["a1"] * k ** 2 + co["a2"] * k + co["a3"]) + co["a4"]
    ex = np.exp(co["c"] * k + co["d"])
    return (co["a"] * p + co["b"]) * ex + (co["e"] * p + co["f"]) * k + co["g"] * p + co["h"]


@pytest.mark.parametrize("kind, co", [("polynomial", POLY), ("sarosi", SAROSI)])
def test_fit_recovers_known_coefficients(kind: str, co: dict[str, float]) -> None:
    p, x = grid()
    got = fit_coefficients(kind, p, 100.0 * x, forward(kind, co, p, x))
    for name, want in co.items():
        assert got[name] == pytest.approx(want, rel=1e-6, abs=1e-6), name


def test_sarosi_d_is_folded_into_a_and_b() -> None:
    """e^(ck + d) only rescales a and b: data made with d = 0.5 give d = 0 and a, b
    times e^0.5, the same force everywhere."""
    p, x = grid()
    co = {**SAROSI, "d": 0.5}
    got = fit_coefficients("sarosi", p, 100.0 * x, forward("sarosi", co, p, x))
    assert got["d"] == 0.0
    assert got["a"] == pytest.approx(co["a"] * math.exp(0.5), rel=1e-6)
    assert got["b"] == pytest.approx(co["b"] * math.exp(0.5), rel=1e-6)


@pytest.mark.parametrize("kind, co", [("polynomial", POLY), ("sarosi", SAROSI)])
def test_inverse_gives_back_the_pressure_and_the_tick_agrees(kind: str, co: dict[str, float],
                                                            tmp_path: Path) -> None:
    p, x = grid(600, 1)
    F = forward(kind, co, p, x)
    rng = np.random.default_rng(2)
    model = fit_static(kind, np.c_[F + rng.normal(0, 2.0, F.size), x], p,
                       input_units=["N", ""])
    assert model.metrics["forward_train"]["nrmse_fit_pct"] > 98.0
    assert model.metrics["train"]["rmse"] < 0.05  # bar: 2 N noise over 65-256 N/bar
    assert model.problems(ENV) == []
    back = load_model(save_model(model, tmp_path / f"{kind}.json"))
    assert back.kind == kind and back.coefficients == model.coefficients
    X = np.c_[F, x][:50]
    batch = back.predict(X)
    ev = back.compile()
    for row, want in zip(X, batch, strict=True):
        assert ev.evaluate(*row) == pytest.approx(want, rel=1e-12, abs=1e-12)
    # Outside the identified ranges: held, flagged, never extrapolated.
    assert ev.evaluate(1e6, 0.1) == model.output.max and ev.clipped and ev.clipped_mask == 1
    ev.evaluate(float(F[0]), float(x[0]))
    assert not ev.clipped or ev.clipped_mask == 0


def test_a_force_model_that_does_not_rise_with_pressure_is_refused() -> None:
    p, x = grid()
    F = 500.0 - 80.0 * p + 0.0 * x  # force falls with pressure: no inverse
    with pytest.raises(ModelError, match="does not rise with pressure"):
        fit_static("polynomial", np.c_[F, x], p, input_units=["N", ""])


def test_one_pressure_does_not_determine_the_model() -> None:
    _, x = grid()
    p = np.full(x.size, 3.0)
    with pytest.raises(ModelError, match="do not determine"):
        fit_static("sarosi", np.c_[forward("sarosi", SAROSI, p, x), x], p,
                   input_units=["N", ""])


def test_wrong_inputs_are_refused() -> None:
    from pamd.models.contract import Variable

    with pytest.raises(ModelError, match="takes the inputs force_n, contraction"):
        PolynomialModel(POLY, [Variable("force_n", "N", 0, 1),
                               Variable("length_mm", "mm", 150, 200)],
                        Variable("pressure_bar", "bar", 0, 6))


def test_the_inverse_is_held_where_the_fitted_gain_turns_negative() -> None:
    """A(k) = 250 - 14 k crosses zero at 17.9 %: contractions past it are held, not
    inverted (data up to 20 %)."""
    co = {"a1": 0.0, "a2": -14.0, "a3": 250.0, "a4": -40.0}
    p, x = grid()
    model = fit_static("polynomial", np.c_[forward("polynomial", co, p, x), x], p,
                       input_units=["N", ""])
    hi = model.inputs[1].max
    assert 0.17 < hi < 250.0 / 14.0 / 100.0 and model.problems(ENV) == []
    ev = model.compile()
    ev.evaluate(300.0, 0.195)
    assert ev.clipped and ev.clipped_mask & 2


def datasheet_map() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The DMSP-20 datasheet force map pamd ships (58 points: p bar, contraction, F N)."""
    import csv
    from importlib import resources

    text = resources.files("pamd.data").joinpath("dmsp20_force_map.csv").read_text()
    rows = list(csv.DictReader(text.splitlines()))
    return tuple(np.array([float(r[k]) for r in rows])  # type: ignore[return-value]
                 for k in ("pressure_bar", "contraction", "force_n"))


def test_fits_to_the_datasheet_map_as_reported() -> None:
    """Seed 002's static use: the force map itself. Sarosi's form fits it to 98.9 %
    NRMSE (RMSE 6.5 N, as rig-physics.md's smooth fit); the 4-parameter polynomial,
    whose offset cannot follow the force at 0 bar, to 67.4 %."""
    from pamd.models.metrics import regression_metrics
    from pamd.models.static_force import gain_offset

    p, x, F = datasheet_map()
    for kind, n, fit_pct, rmse in (("sarosi", 7, 98.90, 6.5), ("polynomial", 4, 67.35, 192.4)):
        co = fit_coefficients(kind, p, 100.0 * x, F)
        A, B = gain_offset(kind, co, 100.0 * x)
        m = regression_metrics(F, A * p + B, n)
        assert m["nrmse_fit_pct"] == pytest.approx(fit_pct, abs=0.05), kind
        assert m["rmse"] == pytest.approx(rmse, rel=0.01), kind

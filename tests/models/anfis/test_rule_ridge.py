"""The consequents' least squares regularised per rule (`TrainingOptions.rule_ridge`,
pamd train's default): where the plain least squares blow up on hanging-load data
(each load's force constant to a fraction of a percent: a force rule's slope has nothing
to fit and trades against its constant), and how the ridge keeps a model that
interpolates between its loads."""

from __future__ import annotations

import numpy as np
import pytest

from pamd.models.anfis import TrainingOptions, fit
from pamd.models.anfis.hybrid import RULE_RIDGE, rule_penalty, solve_consequents


def sweeps(loads_kg: tuple[float, ...], n: int = 60, seed: int = 0
           ) -> tuple[np.ndarray, np.ndarray]:
    """Force and length -> pressure under hanging loads: the force the weight with
    0.6 N of noise, the contraction rising with the pressure and falling with the load
    (a PAM's static map, roughly)."""
    rng = np.random.default_rng(seed)
    X, y = [], []
    for kg in loads_kg:
        p = rng.uniform(0.0, 6.0, n)
        f = kg * 9.81 + rng.normal(0.0, 0.6, n)
        k = 0.25 * (1.0 - np.exp(-150.0 * p / (f + 150.0)))
        X.append(np.c_[f, 200.0 * (1.0 - k)])
        y.append(p)
    return np.concatenate(X), np.concatenate(y)


def held_out(rule_ridge: float) -> tuple[float, float]:
    """(largest |consequent|, RMSE at the held-out 50 kg) of a 5 x 5 model trained at
    15, 30, 65 and 80 kg."""
    X, y = sweeps((15.0, 30.0, 65.0, 80.0))
    Xh, yh = sweeps((50.0,), seed=1)
    model = fit(X, y, TrainingOptions(n_mfs=5, epochs=3, rule_ridge=rule_ridge,
                                      width_factor=1.0)).model
    e = model.predict(Xh) - yh
    return float(np.abs(model.consequents).max()), float(np.sqrt(np.mean(e * e)))


def test_plain_least_squares_blow_up_between_the_loads_and_the_ridge_does_not() -> None:
    plain = held_out(0.0)
    ridged = held_out(RULE_RIDGE)
    assert plain[0] > 1e4 and plain[1] > 10.0, plain  # wild between the bands
    assert ridged[0] < 100.0 and ridged[1] < 0.6, ridged  # 0-6 bar: within a tenth


def test_the_penalty_is_the_rule_s_mass_and_shrinks_toward_the_prior() -> None:
    rng = np.random.default_rng(0)
    wbar = rng.dirichlet(np.ones(4), size=50)
    pen = rule_penalty(wbar, 3, 0.01)
    mass = (wbar ** 2).sum(axis=0)
    np.testing.assert_allclose(pen, np.repeat(0.01 * (mass + mass.mean()), 3))
    assert not rule_penalty(wbar, 3, 0.0).any()
    # a penalty per column: one column penalised alone
    A, b = rng.normal(size=(30, 3)), rng.normal(size=30)
    lam = np.array([0.0, 5.0, 0.0])
    ref = np.linalg.solve(A.T @ A + np.diag(lam), A.T @ b)
    for solver in ("auto", "lstsq"):
        np.testing.assert_allclose(solve_consequents(A, b, solver=solver, ridge=lam), ref,
                                   rtol=1e-10)


def test_negative_ridge_refused() -> None:
    X, y = sweeps((15.0, 30.0))
    with pytest.raises(ValueError, match="rule_ridge"):
        fit(X, y, TrainingOptions(rule_ridge=-1.0))

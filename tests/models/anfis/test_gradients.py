"""Analytic premise gradients against central finite differences, and no NaN at centres."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.models.anfis import error_and_gradient  # noqa: E402


def finite_difference(model, X: np.ndarray, y: np.ndarray, h: float = 1e-6) -> np.ndarray:
    v = model.premise_vector()
    g = np.zeros_like(v)
    for k in range(v.size):
        vp, vm = v.copy(), v.copy()
        vp[k] += h
        vm[k] -= h
        model.set_premise_vector(vp)
        ep, _ = error_and_gradient(model, X, y)
        model.set_premise_vector(vm)
        em, _ = error_and_gradient(model, X, y)
        g[k] = (ep - em) / (2 * h)
    model.set_premise_vector(v)
    return g


def samples_with_centres(model, n: int = 40, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    d = model.n_inputs
    X = rng.uniform(0.0, 1.0, (n, d))
    # One sample sitting exactly on each MF centre (other inputs random).
    rows = []
    for i in range(d):
        for c in model.centres[i]:
            row = rng.uniform(0.0, 1.0, d)
            row[i] = c
            rows.append(row)
    rows.append([model.centres[i][0] for i in range(d)])  # on a centre in every input
    X = np.vstack([X, np.array(rows)])
    y = np.sin(3 * X[:, 0]) + X[:, -1] ** 2
    return X, y


@pytest.mark.parametrize(
    ("mf_type", "n_mfs", "slopes"),
    [
        ("gaussian", (2, 3), None),
        ("gaussian", (3,), None),
        ("gaussian", (2, 2, 2), None),
        ("bell", (2, 3), (1.5, 3.0)),
        ("bell", (3, 2), (0.6, 0.9)),  # b < 1: |z|^(2b-1) is singular-looking at z = 0
    ],
)
def test_gradient_matches_finite_differences(model_factory, mf_type, n_mfs, slopes) -> None:
    model = model_factory(mf_type, n_mfs, slope_range=slopes or (0.7, 3.0))
    X, y = samples_with_centres(model)
    _, g = error_and_gradient(model, X, y)
    assert g.shape == model.premise_vector().shape
    assert np.all(np.isfinite(g))
    g_fd = finite_difference(model, X, y)
    scale = np.max(np.abs(g_fd))
    assert scale > 1e-3  # the check means something
    np.testing.assert_allclose(g, g_fd, rtol=0, atol=1e-6 * scale)


@pytest.mark.parametrize("mf_type", ["gaussian", "bell"])
def test_no_nan_on_a_centre(model_factory, mf_type) -> None:
    model = model_factory(mf_type, (3, 3), slope_range=(0.55, 0.6))
    centre_grid = np.array([[a, b] for a in model.centres[0] for b in model.centres[1]])
    y_hat = model.predict(centre_grid)
    assert np.all(np.isfinite(y_hat))
    half_sse, g = error_and_gradient(model, centre_grid, np.zeros(len(centre_grid)))
    assert np.isfinite(half_sse) and np.all(np.isfinite(g))
    ev = model.compile().evaluate
    for (a, b), yb in zip(centre_grid.tolist(), y_hat, strict=True):
        assert ev(a, b) == pytest.approx(yb, rel=1e-12, abs=1e-12)


def test_gradient_is_zero_where_the_fit_is_exact(model_factory) -> None:
    # Targets produced by the model itself: E = 0 and the gradient vanishes.
    model = model_factory("gaussian", (2, 2))
    X = np.random.default_rng(3).uniform(0, 1, (30, 2))
    half_sse, g = error_and_gradient(model, X, model.predict(X))
    assert half_sse < 1e-25
    np.testing.assert_allclose(g, 0.0, atol=1e-12)

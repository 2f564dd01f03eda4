"""Seed 002's learned kinds on data with a known answer: each of the six SVM kernels
recovers a function in its own span (and a lower-degree kernel does not), with MATLAB's
kernel scales; the MLP's Levenberg-Marquardt and Bayesian regularisation recover a
network's own function, with seed 002's parameter counts; the file and the tick agree
with the batch path for every kernel and solver."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pamd.models import mlp_fit, svr_kernels
from pamd.models.learned import MlpModel, SvrModel
from pamd.models.metrics import regression_metrics
from pamd.models.registry import load_model, save_model

NAMES = ["pressure_bar", "contraction"]
UNITS = ["bar", ""]
FORCE = ("force_n", "N")


def grid(n: int = 15) -> np.ndarray:
    p, x = np.meshgrid(np.linspace(0.0, 6.0, n), np.linspace(-0.04, 0.25, n), indexing="ij")
    return np.c_[p.ravel(), x.ravel()]


def standardised(X: np.ndarray) -> np.ndarray:
    return (X - X.mean(axis=0)) / X.std(axis=0)


def halves(X: np.ndarray, y: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray],
                                                  tuple[np.ndarray, np.ndarray]]:
    """Every other row trains, the rest is held out (the ends of each input train)."""
    tr = np.zeros(len(y), dtype=bool)
    tr[::2] = True
    return (X[tr], y[tr]), (X[~tr], y[~tr])


def in_span(kernel: str, X: np.ndarray) -> np.ndarray:
    """A force-like function exactly in `kernel`'s span on the standardised inputs."""
    u = standardised(X)
    a, b = u[:, 0], u[:, 1]
    if kernel == "linear":
        return 700.0 + 300.0 * a - 200.0 * b
    if kernel == "quadratic":
        return 700.0 + 300.0 * a - 200.0 * b - 90.0 * a * b + 40.0 * b * b
    if kernel == "cubic":
        return 700.0 + 300.0 * a - 90.0 * a * b + 40.0 * b ** 3 - 25.0 * a * a * b
    scale = svr_kernels.kernel_scale(kernel, 2)
    centres = u[[10, 100, 200]]
    weights = (500.0, -300.0, 200.0)
    return 700.0 + sum(w * np.exp(-((u - c) ** 2).sum(axis=1) / scale ** 2)
                       for w, c in zip(weights, centres, strict=True))


def test_kernel_scales_are_matlabs_presets() -> None:
    # seed 002's Tables 6, 10 and 14 list 0.35, 1.4 and 5.7 for its two inputs
    assert svr_kernels.kernel_scale("fine-gaussian", 2) == pytest.approx(math.sqrt(2) / 4)
    assert svr_kernels.kernel_scale("medium-gaussian", 2) == pytest.approx(math.sqrt(2))
    assert svr_kernels.kernel_scale("coarse-gaussian", 2) == pytest.approx(4 * math.sqrt(2))
    assert svr_kernels.kernel_scale("medium-gaussian", 3) == pytest.approx(math.sqrt(3))


@pytest.mark.parametrize("kernel", list(svr_kernels.PRESETS))
def test_each_svm_kernel_recovers_a_function_of_its_span(kernel: str, tmp_path: Path) -> None:
    X = grid()
    y = in_span(kernel, X)
    (Xt, yt), (Xv, yv) = halves(X, y)
    eps = 0.5  # N, of a 2000 N range
    m = SvrModel.fit(Xt, yt, input_names=NAMES, input_units=UNITS, kernel=kernel,
                     svr_c=1e5, svr_epsilon=eps, output=FORCE)
    assert m.kernel == svr_kernels.PRESETS[kernel][0]
    assert m.params["gamma"] == pytest.approx(1.0 / svr_kernels.kernel_scale(kernel, 2) ** 2)
    # held-out points (never trained on) within a few tube widths of the true function
    err = np.abs(m.predict(Xv) - yv)
    assert float(err.max()) < 6 * eps, kernel
    back = load_model(save_model(m, tmp_path / "svr.json"))
    np.testing.assert_allclose(back.predict(Xv), m.predict(Xv), rtol=1e-12)
    ev = back.compile()
    for row, want in zip(Xv[:20], m.predict(Xv[:20]), strict=True):
        assert ev.evaluate(*row) == pytest.approx(float(want), rel=1e-10)
    assert back.output.name == "force_n"


@pytest.mark.parametrize("kernel, lower", [("quadratic", "linear"), ("cubic", "quadratic")])
def test_a_lower_degree_kernel_cannot_fit_it(kernel: str, lower: str) -> None:
    X = grid()
    y = in_span(kernel, X)
    (Xt, yt), (Xv, yv) = halves(X, y)
    m = SvrModel.fit(Xt, yt, input_names=NAMES, input_units=UNITS, kernel=lower,
                     svr_c=1e5, svr_epsilon=0.5, output=FORCE)
    assert float(np.abs(m.predict(Xv) - yv).max()) > 20.0


def test_svr_defaults_are_fitrsvms_iqr_rules() -> None:
    X = grid()
    y = in_span("cubic", X)
    m = SvrModel.fit(X, y, input_names=NAMES, input_units=UNITS, output=FORCE)
    q75, q25 = np.percentile(y, [75, 25])
    fit = m.provenance["fit"]
    assert fit["kernel"] == "medium-gaussian"
    assert fit["box_constraint"] == pytest.approx((q75 - q25) / 1.349)
    assert fit["epsilon"] == pytest.approx((q75 - q25) / 13.49)


def teacher(X: np.ndarray) -> np.ndarray:
    """A 2-neuron tanh network of the inputs scaled to [-1, 1] (as the fit scales them)."""
    lo, hi = X.min(axis=0), X.max(axis=0)
    u = (X - (hi + lo) / 2) / ((hi - lo) / 2)
    return 600.0 + 800.0 * np.tanh(1.3 * u[:, 0] - 0.8 * u[:, 1] + 0.2) \
        - 500.0 * np.tanh(-0.5 * u[:, 0] + 1.7 * u[:, 1] - 0.4)


@pytest.mark.parametrize("solver, fit_pct", [("lm", 99.9), ("br", 99.5)])
def test_mlp_solvers_recover_a_network_function(solver: str, fit_pct: float,
                                                tmp_path: Path) -> None:
    X = grid()
    y = teacher(X)
    (Xt, yt), (Xv, yv) = halves(X, y)
    best = max((MlpModel.fit(Xt, yt, input_names=NAMES, input_units=UNITS, hidden=4,
                             max_iter=300, solver=solver, seed=s, output=FORCE,
                             validation=(Xv, yv) if solver == "lm" else None)
                for s in range(3)), key=lambda m: m.metrics["train"]["nrmse_fit_pct"])
    held = regression_metrics(yv, best.predict(Xv), best.n_params)
    assert held["nrmse_fit_pct"] > fit_pct, solver
    assert best.provenance["fit"]["solver"] == solver
    back = load_model(save_model(best, tmp_path / "mlp.json"))
    ev = back.compile()
    for row, want in zip(Xv[:10], best.predict(Xv[:10]), strict=True):
        assert ev.evaluate(*row) == pytest.approx(float(want), rel=1e-10)


def test_bayesian_regularisation_tames_an_oversized_network() -> None:
    """20 neurons (81 parameters) on 40 noisy points: BR's effective parameters stay
    well below 81, and it generalises better than plain LM trained to convergence."""
    rng = np.random.default_rng(3)
    X = np.c_[rng.uniform(0, 6, 80), rng.uniform(-0.04, 0.25, 80)]
    X[:4] = [[0, -0.04], [6, -0.04], [0, 0.25], [6, 0.25]]
    y = teacher(X) + rng.normal(0, 20.0, 80)
    Xt, yt, Xv, yv = X[:40], y[:40], X[40:], teacher(X[40:])
    br = MlpModel.fit(Xt, yt, input_names=NAMES, input_units=UNITS, hidden=20,
                      max_iter=300, solver="br", output=FORCE)
    lm = MlpModel.fit(Xt, yt, input_names=NAMES, input_units=UNITS, hidden=20,
                      max_iter=300, solver="lm", output=FORCE)
    assert br.n_params == 81 and br.provenance["fit"]["effective_parameters"] < 40
    err = {k: float(np.sqrt(np.mean((m.predict(Xv) - yv) ** 2))) for k, m in
           (("br", br), ("lm", lm))}
    assert err["br"] < err["lm"]


@pytest.mark.parametrize("hidden, params", [(1, 5), (2, 9), (5, 21), (10, 41), (20, 81)])
def test_mlp_parameter_counts_are_seed_002s(hidden: int, params: int) -> None:
    X = grid(6)
    m = MlpModel.fit(X, teacher(X), input_names=NAMES, input_units=UNITS, hidden=hidden,
                     max_iter=2, output=FORCE)
    assert m.n_params == params


def test_the_jacobian_is_the_derivative_of_the_output() -> None:
    rng = np.random.default_rng(0)
    S = rng.uniform(-1, 1, (7, 3))
    h = 4
    w = rng.normal(size=h * 5 + 1)
    y, a = mlp_fit.network_outputs(w, S, h)
    J = mlp_fit.jacobian(w, S, a, h)
    for k in range(w.size):
        dw = np.zeros_like(w)
        dw[k] = 1e-6
        up, down = mlp_fit.network_outputs(w + dw, S, h), mlp_fit.network_outputs(w - dw, S, h)
        num = (up[0] - down[0]) / 2e-6
        np.testing.assert_allclose(J[:, k], num, rtol=1e-5, atol=1e-8)

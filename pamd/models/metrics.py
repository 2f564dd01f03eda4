"""Regression and model-comparison metrics: measured values y against model values.

Role: one place for the figures pamd reports about a model or a tracking run (the
ANFIS inverse model's fit, and equally a controller's tracking error), so that every
report uses the same definitions. Plain numpy; no model knowledge except the
parameter count that AIC and SBC need.

Definitions (n samples, e = y - y_hat; natural logarithms):

* ``mse`` = mean(e^2); ``rmse`` = sqrt(mse); ``mae`` = mean(|e|)
* ``half_mse`` = (1/n) sum(e^2 / 2) = mse / 2: seed 001's eq. 7, the error it calls MSE
  (its figures, 4.33e-5 bar^2 for the MGA, are on this basis; pamd's mse is twice it)
* ``max_abs_error`` = max |e|
* ``max_deviation_pct`` = max |e| / (max(y) - min(y)) * 100: the "maximum deviation"
  of seeds 000/001, in % of the measured output range
* ``sse`` = sum(e^2) (seed 002, eq. A1)
* ``nrmse_fit_pct`` = 100 * (1 - ||e|| / ||y - mean(y)||) (seed 002, eq. A2; 100 % is
  a perfect fit, 0 % is no better than the mean, negative is worse)
* ``aic`` = n ln(SSE / n) + 2 p (seed 002, eq. A8)
* ``sbc`` = n ln(SSE / n) + p ln(n) (seed 002, eq. A5)
* ``ndei`` = rmse / std(y) (non-dimensional error index, Jang; population std)

Undefined values are NaN rather than an exception: the percentage/ratio metrics when
y is constant, AIC/SBC when SSE = 0 (a perfect fit gives -inf there).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

METRIC_NAMES: tuple[str, ...] = (
    "mse",
    "half_mse",
    "rmse",
    "mae",
    "max_abs_error",
    "max_deviation_pct",
    "sse",
    "nrmse_fit_pct",
    "aic",
    "sbc",
    "ndei",
)


def regression_metrics(y_true: ArrayLike, y_pred: ArrayLike, n_params: int) -> dict[str, float]:
    """All metrics of the module docstring as a dict of plain floats.

    `y_true` are the measured values, `y_pred` the model's, same length (>= 1);
    `n_params` is the number of fitted model parameters (for AIC and SBC).
    """
    y = np.asarray(y_true, dtype=np.float64).ravel()
    yh = np.asarray(y_pred, dtype=np.float64).ravel()
    if y.shape != yh.shape:
        raise ValueError(f"y_true has {y.size} values but y_pred has {yh.size}")
    if y.size == 0:
        raise ValueError("no samples to compute metrics on")
    if n_params < 0:
        raise ValueError(f"n_params must be >= 0, got {n_params}")
    n = y.size
    e = y - yh
    sse = float(np.dot(e, e))
    mse = sse / n
    max_abs = float(np.max(np.abs(e)))
    y_range = float(np.max(y) - np.min(y))
    dev = y - np.mean(y)
    ss_dev = float(np.dot(dev, dev))
    std = math.sqrt(ss_dev / n)
    nan = float("nan")
    log_mse = math.log(mse) if mse > 0 else nan
    return {
        "mse": mse,
        "half_mse": 0.5 * mse,
        "rmse": math.sqrt(mse),
        "mae": float(np.mean(np.abs(e))),
        "max_abs_error": max_abs,
        "max_deviation_pct": max_abs / y_range * 100.0 if y_range > 0 else nan,
        "sse": sse,
        "nrmse_fit_pct": 100.0 * (1.0 - math.sqrt(sse) / math.sqrt(ss_dev)) if ss_dev > 0 else nan,
        "aic": n * log_mse + 2.0 * n_params,
        "sbc": n * log_mse + n_params * math.log(n),
        "ndei": math.sqrt(mse) / std if std > 0 else nan,
    }

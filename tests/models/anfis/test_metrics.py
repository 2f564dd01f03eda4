"""Metrics against values computed by hand on tiny arrays (pamd.models.metrics)."""

from __future__ import annotations

import math
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pamd.models.metrics import METRIC_NAMES, regression_metrics  # noqa: E402


def test_hand_computed_values() -> None:
    # e = y - y_hat = [-0.5, 0, 1, 0]; SSE = 1.25; y mean 2.5, sum (y - mean)^2 = 5.
    m = regression_metrics([1.0, 2.0, 3.0, 4.0], [1.5, 2.0, 2.0, 4.0], n_params=2)
    assert set(m) == set(METRIC_NAMES)
    assert m["sse"] == pytest.approx(1.25)
    assert m["mse"] == pytest.approx(0.3125)
    assert m["rmse"] == pytest.approx(math.sqrt(0.3125))
    assert m["mae"] == pytest.approx(0.375)
    assert m["max_abs_error"] == pytest.approx(1.0)
    assert m["max_deviation_pct"] == pytest.approx(100.0 / 3.0)  # 1 / (4 - 1)
    assert m["nrmse_fit_pct"] == pytest.approx(50.0)  # 1 - sqrt(1.25) / sqrt(5) = 1/2
    assert m["aic"] == pytest.approx(4 * math.log(0.3125) + 2 * 2)
    assert m["sbc"] == pytest.approx(4 * math.log(0.3125) + 2 * math.log(4))
    assert m["ndei"] == pytest.approx(0.5)  # sqrt(0.3125) / sqrt(5 / 4)
    assert all(isinstance(v, float) for v in m.values())


def test_aic_sbc_numbers() -> None:
    # Explicit numbers, in case a formula and its test share a mistake.
    m = regression_metrics([1.0, 2.0, 3.0, 4.0], [1.5, 2.0, 2.0, 4.0], n_params=2)
    assert m["aic"] == pytest.approx(-0.652603239, abs=1e-8)
    assert m["sbc"] == pytest.approx(-1.880014517, abs=1e-8)


def test_perfect_fit_and_constant_output_give_nan_not_errors() -> None:
    m = regression_metrics([1.0, 2.0], [1.0, 2.0], n_params=1)
    assert m["sse"] == 0.0 and m["nrmse_fit_pct"] == 100.0 and m["ndei"] == 0.0
    assert math.isnan(m["aic"]) and math.isnan(m["sbc"])
    c = regression_metrics([3.0, 3.0, 3.0], [3.0, 2.0, 3.0], n_params=1)
    assert math.isnan(c["max_deviation_pct"]) and math.isnan(c["nrmse_fit_pct"])
    assert math.isnan(c["ndei"]) and c["max_abs_error"] == 1.0


def test_shape_mismatch_refused() -> None:
    with pytest.raises(ValueError):
        regression_metrics(np.zeros(3), np.zeros(4), n_params=1)
    with pytest.raises(ValueError):
        regression_metrics([], [], n_params=1)

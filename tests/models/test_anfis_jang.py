"""The ANFIS library's defaults on Jang's (1993) checks, as bench/anfis_jang.py reports
them (deterministic: no random choice in `fit` without a validation fraction). The
defaults were chosen on held-out training data and other problems (`--select`), never
on these check sets; these tests guard the reported figures, so a change of the
defaults or of the training shows here."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest

from pamd.models.anfis import TrainingOptions, fit
from pamd.models.anfis.hybrid import WIDTH_STARTS
from tests.benchmod import bench_module


def bench() -> ModuleType:
    return bench_module("anfis_jang")


#: Where the sinc check RMSE of the default starts lands, on any machine and build. The
#: wide start's 500 epochs of step-size-adapted descent are chaotic in the last bits of
#: the data: with every training target moved by at most one ulp at random, 80 fits (40
#: each with numpy 2.4's AVX-512 and AVX2 paths) gave 0.0052-0.0282, median 0.011, 2 of
#: 80 above the 0.025 goal; the data as it is gives 0.0058 on an AVX-512 build and 0.0142
#: on an AVX2-only one (issue 38: a pin of 0.00577 +- 1e-4 held on one build only). The
#: narrow start (width 1) is not: 0.034421 in all 24 such fits, both paths.
SINC_RMSE_RANGE = (0.005, 0.030)


def test_sinc_with_the_library_defaults() -> None:
    """4 x 4 Gaussian MFs, 500 epochs, the default starts WIDTH_STARTS: the wide start
    (3) is kept on training error and lands within SINC_RMSE_RANGE (0.0058 on one build,
    0.0142 on another: the training's sensitivity, not the build's fault); one start at
    width 1 (MATLAB's layout, the old default) stalls at 0.0344 on every build."""
    b = bench()
    p = b.PROBLEMS["sinc"]
    train, check = p.data()
    result = fit(*train, TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs))
    got = b.rmse(result.model.predict, *check)
    assert TrainingOptions().width_factor == WIDTH_STARTS == (1.0, 3.0)
    assert result.model.provenance["training"]["width_starts"]["kept"] == 3.0
    lo, hi = SINC_RMSE_RANGE
    assert lo <= got <= hi, got
    one = fit(*train, TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs, width_factor=1.0))
    assert b.rmse(one.model.predict, *check) == pytest.approx(0.0344, abs=2e-4)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_sinc_with_the_defaults_is_chaotic_in_the_last_bits() -> None:
    """The finding behind SINC_RMSE_RANGE, on this build: 12 fits with each training
    target moved by at most one ulp spread the check RMSE by a factor of more than 1.5,
    every one within the range; the narrow start gives the same figure every time."""
    b = bench()
    p = b.PROBLEMS["sinc"]
    (X, y), check = p.data()
    rng = np.random.default_rng(1)
    wide, narrow = [], []
    for _ in range(12):
        yp = y + rng.integers(-1, 2, size=y.shape) * np.spacing(y)
        fitted = fit(X, yp, TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs))
        wide.append(b.rmse(fitted.model.predict, *check))
    for _ in range(3):
        yp = y + rng.integers(-1, 2, size=y.shape) * np.spacing(y)
        fitted = fit(X, yp, TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs, width_factor=1.0))
        narrow.append(b.rmse(fitted.model.predict, *check))
    assert max(wide) / min(wide) > 1.5, wide
    assert all(SINC_RMSE_RANGE[0] <= g <= SINC_RMSE_RANGE[1] for g in wide), wide
    assert max(narrow) - min(narrow) < 1e-9, narrow


@pytest.mark.slow
@pytest.mark.timeout(1800)  # four Mackey-Glass fits of 500 epochs: minutes on a busy machine
def test_mackey_glass_with_the_library_defaults() -> None:
    """2 Gaussian MFs per input, 500 epochs: 0.00253, just above the goal of 0.0025
    (Jang 1993: 0.0016), with the default starts and from width 1 alone (width 1 is
    kept: training RMSE 0.00119 against 0.00154)."""
    b = bench()
    assert b.checks()["mackey-glass"] == pytest.approx(0.00253, abs=5e-5)
    one = b.checks(TrainingOptions(width_factor=1.0))["mackey-glass"]
    assert one == pytest.approx(0.00253, abs=5e-5)


@pytest.mark.slow
@pytest.mark.timeout(1800)  # two Mackey-Glass fits of 500 epochs
def test_mackey_glass_gap_is_a_forecast_gap() -> None:
    """Why no training setting reaches 0.0025 (docs/explanation/inverse-model.md,
    bench/anfis_jang.py --diagnose):
    on the training series' last fifth in time (a forecast, as the check is) the
    held-out RMSE is lowest early (epoch 43, 0.00202) and rises to 0.00245 by epoch 500
    while the training RMSE keeps falling; on a random fifth (points between the data
    fitted) it falls to the end (0.00165). Measured on training data only."""
    got = bench().held_out_by_epoch()
    val, trn = got["last fifth in time"]
    assert int(val.argmin()) + 1 < 100 and val.min() == pytest.approx(0.00202, abs=5e-5)
    assert val[-1] == pytest.approx(0.00245, abs=5e-5) and val[-1] > 1.15 * val.min()
    assert trn[-1] < trn[49]  # the fit to the data seen goes on improving
    val, _ = got["random fifth"]
    assert val[-1] == pytest.approx(0.00165, abs=5e-5) and val[-1] <= 1.01 * val.min()

"""The ANFIS library's defaults on Jang's (1993) checks, as bench/anfis_jang.py reports
them (deterministic: no random choice in `fit` without a validation fraction). The
defaults were chosen on held-out training data and other problems (`--select`), never
on these check sets; these tests guard the reported figures, so a change of the
defaults or of the training shows here."""

from __future__ import annotations

from types import ModuleType

import pytest

from pamd.models.anfis import TrainingOptions, fit
from pamd.models.anfis.training import WIDTH_STARTS
from tests.benchmod import bench_module


def bench() -> ModuleType:
    return bench_module("anfis_jang")


def test_sinc_with_the_library_defaults() -> None:
    """4 x 4 Gaussian MFs, 500 epochs, the default starts WIDTH_STARTS: the wide start
    (3) is kept on training error and reaches 0.0058 (goal <= 0.025); one start at width
    1 (MATLAB's layout, the old default) stalls at 0.0344."""
    b = bench()
    p = b.PROBLEMS["sinc"]
    train, check = p.data()
    result = fit(*train, TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs))
    got = b.rmse(result.model.predict, *check)
    assert TrainingOptions().width_factor == WIDTH_STARTS == (1.0, 3.0)
    assert result.model.provenance["training"]["width_starts"]["kept"] == 3.0
    assert got == pytest.approx(0.00577, abs=1e-4) and got <= 0.025
    one = fit(*train, TrainingOptions(n_mfs=p.n_mfs, epochs=p.epochs, width_factor=1.0))
    assert b.rmse(one.model.predict, *check) == pytest.approx(0.0344, abs=2e-4)


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

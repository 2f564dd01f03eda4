"""bench/anfis_mackey_glass_family.py: the library's defaults on Mackey-Glass trajectories
other than the reference, and the integrator that made the reference. The figures are
deterministic (no random choice in `fit` without a validation fraction); these tests
guard the ones docs/explanation/inverse-model.md reports."""

from __future__ import annotations

import math
from types import ModuleType

import numpy as np
import pytest

from tests.benchmod import bench_module


def bench() -> ModuleType:
    return bench_module("anfis_mackey_glass_family")


#: values of ../shared/reference/mackey_glass.csv (t: x) as the file prints them: the
#: file lies outside the repository (CI has no copy), so the default run checks these
REFERENCE_VALUES = {1: 1.08580490165, 17: 0.227688680408, 18: 0.2525439794,
                    100: 0.941167760185, 618: 1.11081060936, 1117: 1.1786491805,
                    1123: 1.00747607614, 1200: 1.08754176985}


def test_the_generator_is_the_reference_files_integrator() -> None:
    """RK4, dt 0.1, the delayed term at half steps the mean of its neighbours: the
    reference file's values to their printed digits, from the start to the check's last
    target. Holding the delayed term instead handles the jump at t = 17 otherwise, and
    by the check's stretch the trajectory is another."""
    b = bench()
    x = b.series()
    assert x.size == 1201
    for t, value in REFERENCE_VALUES.items():
        assert x[t] == pytest.approx(value, abs=1e-11), t
    hold = b.series(1.2, 0.1, "hold")
    assert abs(hold[17] - x[17]) < 0.02  # the same start ...
    assert np.abs(hold - x)[618:1124].max() > 0.3  # ... not the same check stretch
    assert 1.2 not in b.FAMILY_X0 and len(b.FAMILY_X0) == 20
    with pytest.raises(ValueError, match="delayed must be one of"):
        b.series(1.2, 0.1, "linear")


@pytest.mark.slow
@pytest.mark.timeout(1800)  # 21 Mackey-Glass fits of 500 epochs
def test_the_family_with_the_library_defaults() -> None:
    """Over 20 other trajectories the defaults' check RMSE has median 0.00224 and 13
    of 20 at or below the goal of 0.0025; the reference's 0.00253 is above 13 of them,
    and 39 % of its squared error lies in 10 points of two episodes."""
    b = bench()
    reference = bench_module("anfis_mackey_glass").reference_series()  # or its integrator's
    assert np.abs(b.series()[: reference.size] - reference).max() < 1e-9  # the whole file
    got = np.array([c for _, c in b.family(jobs=2).values()])
    assert np.median(got) == pytest.approx(0.00224, abs=5e-5)
    assert int((got <= b.GOAL).sum()) == 13
    _, e = b.check_errors(reference)
    ref = math.sqrt(float(e @ e) / e.size)
    assert ref == pytest.approx(0.00253, abs=5e-5) and int((got < ref).sum()) == 13
    worst = np.sort(e**2)[-10:]
    assert worst.sum() / (e @ e) == pytest.approx(0.39, abs=0.02)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_another_integration_of_the_same_start() -> None:
    """The reference's x(0) = 1.2 with the delayed term held over the step: check RMSE
    0.00142 with the same defaults (training 0.00136): a check error as low as the
    training error, as in Jang's report, where the reference's is twice it."""
    b = bench()
    train, check = b.check_rmse(b.series(1.2, 0.1, "hold"))
    assert check == pytest.approx(0.00142, abs=5e-5)
    assert train == pytest.approx(0.00136, abs=5e-5)

"""Fixtures shared by the control tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pamd.models.anfis import TrainingOptions, fit, save
from pamd.muscle_type import force_model, pressure_for_force


@pytest.fixture(scope="module")
def static_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """(force, length) -> pressure of the sim's own force map, no friction: a model the
    way `pamd train` writes it, in 0.2 s."""
    fm = force_model("map")
    rng = np.random.default_rng(0)
    F = rng.uniform(100.0, 800.0, 1500)
    x = rng.uniform(-0.03, 0.22, 1500)
    p = np.array([pressure_for_force(fm, f, c, 6.0) for f, c in zip(F, x, strict=True)])
    ok = (p > 0.05) & (p < 5.95)
    res = fit(np.c_[F[ok], 200.0 * (1.0 - x[ok])], p[ok],
              TrainingOptions(n_mfs=[2, 4], epochs=30),
              input_names=["force_n", "length_mm"], input_units=["N", "mm"],
              output_name="pressure_bar", output_unit="bar")
    return save(res.model, tmp_path_factory.mktemp("model") / "static.json")

"""The step finder and the model checks that refuse what no loop can be tuned on."""

from __future__ import annotations

import numpy as np
import pytest

from pamd.client.tune.step_responses import (
    StepResponse,
    check_model,
    fit_all,
    mean_model,
    pressure_gains,
    steps_in,
)
from pamd.loop.control.tuning import Fopdt, IdentificationError

PLANT = Fopdt(0.95, 0.013, 0.0126)


def recorded(amplitude: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(0.0, 1.0, 0.001)
    u = np.where(t >= 0.3005, 3.0 + amplitude, 3.0)
    y = 2.85 + PLANT.step_response(t - 0.3005, amplitude)
    return t, u, y


def test_a_step_is_found_at_its_edge_and_fitted() -> None:
    t, u, y = recorded(0.2)
    (step,) = steps_in(t, u, y, 0.4)
    assert step.t_step_s == pytest.approx(0.3005, abs=1e-6)
    model = mean_model(fit_all([step]))
    check_model("pressure", fit_all([step]), model)
    assert model.gain == pytest.approx(0.95, rel=0.01)
    assert model.dead_time_s == pytest.approx(0.0126, abs=0.0005)
    # the SIMC gains of the analytic plant
    assert pressure_gains(model).kp == pytest.approx(0.013 / (0.95 * 2 * 0.0126), rel=0.05)


def test_non_physical_models_are_refused() -> None:
    t, u, y = recorded(0.2)
    fits = fit_all(steps_in(t, u, 2 * y[0] - y, 0.4))  # the pressure falls: wrong sign
    with pytest.raises(IdentificationError, match="more command must give more pressure"):
        check_model("pressure", fits, mean_model(fits))
    fits = fit_all(steps_in(t, u, y, 0.4))
    with pytest.raises(IdentificationError, match="more pressure must shorten"):
        check_model("position", fits, mean_model(fits))


def test_no_response_is_refused() -> None:
    t, u, _ = recorded(0.2)
    flat = 2.85 + 0.001 * np.sin(np.arange(t.size))
    with pytest.raises(IdentificationError, match="within the noise"):
        fit_all([StepResponse("x", 0.3005, 0.2, t, flat)])


def test_a_response_that_is_not_first_order_is_refused() -> None:
    t, u, y = recorded(0.2)
    ringing = y + 0.1 * np.sin(2 * np.pi * 15 * t) * (t > 0.32)
    fits = fit_all(steps_in(t, u, ringing, 0.4))
    with pytest.raises(IdentificationError, match="not first order plus dead time"):
        check_model("pressure", fits, mean_model(fits))

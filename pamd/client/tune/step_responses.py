"""Step responses and the rules that turn them into gains: what `pamd tune` and
bench/tune_pressure_loop.py share.

- `StepResponse`: one recorded step of a loop's input and its output around it.
- `steps_in`: the steps of a recorded input column (a recording's `valve_cmd_bar` or
  `setpoint_bar`), each with the output from 50 ms before it.
- `fit_all`, `mean_model`: an FOPDT fit per step (`pamd.loop.control.tuning.fit_step`) and
  the design model, their mean.
- `check_model`: refuse a model no loop can be tuned on (wrong sign, no lag, a poor
  fit) with the reason.
- `pressure_gains`, `position_gains`: Skogestad's SIMC PI (tau_c = dead time) and the
  rate feedforward (dead time + lag).

Offline code (numpy): it runs on recorded data after a test, never in the tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pamd.config.control_schema import (
    PID_KI_MAX_PER_S,
    PID_KP_MAX,
    POSITION_KI_MAX_BAR_PER_MM_S,
    POSITION_KP_MAX_BAR_PER_MM,
)
from pamd.loop.control.tuning import (
    Fopdt,
    IdentificationError,
    fit_step,
    rate_feedforward_s,
    simc_pi,
)

#: A fit whose rms error exceeds this fraction of the step's change is not a FOPDT
#: response (an oscillation, a saturated fill, a disturbance in the record).
MAX_RELATIVE_FIT_ERROR = 0.15


@dataclass(frozen=True)
class StepResponse:
    """One recorded step: the input's change at `t_step_s` and the output around it."""

    label: str
    t_step_s: float
    amplitude: float
    t_s: np.ndarray
    y: np.ndarray


@dataclass(frozen=True)
class PressureGains:
    kp: float
    ki_per_s: float
    rate_feedforward_s: float


@dataclass(frozen=True)
class PositionGains:
    kp_bar_per_mm: float
    ki_bar_per_mm_s: float


def steps_in(t_s: np.ndarray, u: np.ndarray, y: np.ndarray, record_s: float,
             min_step: float = 0.05, pre_s: float = 0.05) -> list[StepResponse]:
    """The steps of input `u` (a change of more than `min_step` within 50 ms, at least
    0.2 s after the last), each with `y` from `pre_s` before it to `record_s` after.
    A step's time is the middle of its edge: where `u` crosses half its change."""
    steps: list[StepResponse] = []
    last = -np.inf
    for k in np.nonzero(np.abs(np.diff(u)) > 0.02)[0]:
        if t_s[k] - last < 0.2:
            continue
        after = min(int(np.searchsorted(t_s, t_s[k] + 0.05)), len(u) - 1)
        u0 = float(u[max(k - 1, 0)])
        amp = float(u[after] - u0)
        if abs(amp) < min_step:
            continue
        last = t_s[k]
        t_step = _half_crossing(t_s, u, int(k), u0, amp)
        sel = (t_s >= t_step - pre_s) & (t_s <= t_step + record_s)
        label = f"{u0:.2f} bar {'up' if amp > 0 else 'down'}"
        steps.append(StepResponse(label, t_step, amp, t_s[sel], y[sel]))
    return steps


def _half_crossing(t_s: np.ndarray, u: np.ndarray, k: int, u0: float, amp: float) -> float:
    """The time `u` passes u0 + amp/2 after sample k (interpolated between samples)."""
    half = u0 + 0.5 * amp
    j = k
    while j + 1 < len(u) and (u[j + 1] - half) * np.sign(amp) < 0.0:
        j += 1
    if j + 1 >= len(u):
        return float(t_s[k])
    a, b = float(u[j]), float(u[j + 1])
    frac = (half - a) / (b - a) if b != a else 1.0
    return float(t_s[j] + frac * (t_s[j + 1] - t_s[j]))


def fit_all(steps: list[StepResponse]) -> list[tuple[StepResponse, Fopdt]]:
    return [(s, fit_step(s.t_s, s.y, s.t_step_s, s.amplitude)) for s in steps]


def mean_model(fits: list[tuple[StepResponse, Fopdt]]) -> Fopdt:
    if not fits:
        raise IdentificationError("no step was fitted")
    g = float(np.mean([f.gain for _, f in fits]))
    tau = float(np.mean([f.tau_s for _, f in fits]))
    theta = float(np.mean([f.dead_time_s for _, f in fits]))
    return Fopdt(g, tau, theta)


def check_model(loop: str, fits: list[tuple[StepResponse, Fopdt]], model: Fopdt) -> None:
    """Refuse (IdentificationError) a model the loop cannot be tuned on."""
    for s, f in fits:
        change = abs(f.gain * s.amplitude)
        if not all(math.isfinite(v) for v in (f.gain, f.tau_s, f.dead_time_s, f.rms_error)):
            raise IdentificationError(f"step {s.label}: the fit did not converge (non-finite "
                                      "parameters)")
        if f.rms_error > MAX_RELATIVE_FIT_ERROR * change:
            raise IdentificationError(
                f"step {s.label}: the response is not first order plus dead time (fit error "
                f"{f.rms_error:.3g} is {100 * f.rms_error / change:.0f} % of its change, "
                f"over {100 * MAX_RELATIVE_FIT_ERROR:.0f} %): check for saturation, "
                "oscillation or a disturbance during the run")
    if loop == "pressure" and not model.gain > 0.0:
        raise IdentificationError(f"the pressure loop's gain is {model.gain:.3g} bar/bar: "
                                  "more command must give more pressure (check the valve "
                                  "channel's scaling and the pressure sensor)")
    if loop == "position" and not model.gain < 0.0:
        raise IdentificationError(f"the position loop's gain is {model.gain:.3g} mm/bar: "
                                  "more pressure must shorten the muscle (check the length "
                                  "sensor's sign and that the load hangs freely)")
    if not model.tau_s > 1e-4:
        raise IdentificationError(f"the fitted lag is {1e3 * model.tau_s:.2g} ms: no "
                                  "first-order response to tune on")


def pressure_gains(model: Fopdt) -> PressureGains:
    pi = simc_pi(model, kp_max=PID_KP_MAX, ki_max=PID_KI_MAX_PER_S)
    return PressureGains(pi.kp, pi.ki_per_s, rate_feedforward_s(model))


def position_gains(model: Fopdt) -> PositionGains:
    pi = simc_pi(Fopdt(abs(model.gain), model.tau_s, model.dead_time_s),
                 kp_max=POSITION_KP_MAX_BAR_PER_MM, ki_max=POSITION_KI_MAX_BAR_PER_MM_S)
    return PositionGains(pi.kp, pi.ki_per_s)

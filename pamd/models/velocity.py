"""The muscle's velocity: one filtered derivative of the length, used by the control
tick and by the training data extraction alike (so a model trained on it sees the
same signal the tick feeds it).

Per tick the length changes by less than one encoder step (0.01 mm), so the raw
backward difference is mostly quantisation noise. The velocity is that difference
passed through a first-order low-pass with time constant `VELOCITY_WINDOW_S`:

    v_k = v_{k-1} + a (( L_k - L_{k-1}) / dt_k - v_{k-1}),   a = dt_k / (window + dt_k)

in mm/s for L in mm. The first sample (no previous length) leaves v at its start
value (0). `velocity_step` is that one step as a plain function of floats: the tick
calls it inline (no allocation) for the recorded velocity, `VelocityFilter` wraps it
for a second signal (the length target fed to a model), and `filtered_velocity` runs
it over a recorded column for training. The window is a parameter: the recorded
signal uses `VELOCITY_WINDOW_S`, a model states its own in its file (default
`MODEL_VELOCITY_WINDOW_S`) and the tick feeds it exactly that.
"""

from __future__ import annotations

import math
from typing import Protocol, SupportsFloat

from pamd.wire.declare.jsonsafe import JsonObject

VELOCITY_WINDOW_S = 0.05
"""Time constant of the recorded velocity (`velocity_mm_s` of the tick record), s."""

MODEL_VELOCITY_WINDOW_S = 3.0
"""Default time constant of a model's velocity input, s. A long window makes the
filtered velocity a memory of which way, and how far, the muscle has moved lately:
what tells the inflating branch of the hysteresis from the deflating one, including
the slow friction reversal at the top of a sweep (bench/anfis_inverse_sim.py: 0.05 s
gives a 3-input model 7-12 % maximum deviation on an unseen load, 2.5-4 s about
1-1.5 %). The window is stored in the model file and the tick filters with it."""

VELOCITY_METHOD = ("first-order low-pass of the backward difference: v += dt / (window_s + dt)"
                   " * ((length_mm - previous length_mm) / dt - v), v = 0 at the first sample")


def velocity_step(v_mm_s: float, prev_mm: float, length_mm: float, dt_s: float,
                  window_s: float = VELOCITY_WINDOW_S) -> float:
    """One filter step: the new velocity (mm/s) after a length reading taken dt_s after
    `prev_mm`. A NaN `prev_mm` (no previous reading) leaves the velocity unchanged."""
    if prev_mm == prev_mm and dt_s > 0.0:
        return v_mm_s + dt_s / (window_s + dt_s) * ((length_mm - prev_mm) / dt_s - v_mm_s)
    return v_mm_s


class VelocityFilter:
    """`velocity_step` with its state, for one signal (e.g. a length target)."""

    __slots__ = ("window_s", "value", "prev_mm")

    def __init__(self, window_s: float = VELOCITY_WINDOW_S) -> None:
        self.window_s = window_s
        self.value = 0.0
        self.prev_mm = math.nan

    def reset(self, length_mm: float = math.nan, velocity_mm_s: float = 0.0) -> None:
        self.prev_mm = length_mm
        self.value = velocity_mm_s

    def update(self, length_mm: float, dt_s: float) -> float:
        self.value = velocity_step(self.value, self.prev_mm, length_mm, dt_s, self.window_s)
        self.prev_mm = length_mm
        return self.value


class Series(Protocol):
    """A run's samples in time order: a list or a 1-d numpy array."""

    def __len__(self) -> int: ...
    def __getitem__(self, i: int, /) -> SupportsFloat: ...


def filtered_velocity(t_s: Series, length_mm: Series,
                      window_s: float = VELOCITY_WINDOW_S) -> list[float]:
    """The tick's velocity (mm/s) over a recorded run: `velocity_step` applied sample by
    sample with each sample's own dt. Run it at the recording's full rate, before
    any decimation, or it is not the signal the tick computes."""
    out = [0.0] * len(length_mm)
    v, prev, t_prev = 0.0, math.nan, math.nan
    for i in range(len(out)):
        t, x = float(t_s[i]), float(length_mm[i])
        v = velocity_step(v, prev, x, t - t_prev, window_s)
        out[i] = v
        prev, t_prev = x, t
    return out


def derivation(window_s: float = MODEL_VELOCITY_WINDOW_S) -> JsonObject:
    """How a model's `velocity_mm_s` input is computed (stored in the model file)."""
    return {"derived_from": "length_mm", "unit": "mm/s", "window_s": window_s,
            "method": VELOCITY_METHOD, "function": "pamd.models.velocity.velocity_step"}

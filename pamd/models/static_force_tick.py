"""The tick's evaluators of the static force kinds (`pamd.models.static_force`): the
closed-form inverse p = (F - B(k)) / A(k) and the forward model F = A(k) p + B(k), one
sample at a time in plain Python, inputs (and the inverse's output) held to their
identified ranges and flagged."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

from pamd.models.contract import Variable

#: The least pressure gain A(k) (N/bar) accepted over the identified range.
MIN_GAIN_N_PER_BAR = 1.0


class ForceMap(Protocol):
    """What the evaluators need of a static force model."""

    @property
    def inputs(self) -> Sequence[Variable]: ...
    @property
    def output(self) -> Variable: ...
    def scalar_gain_offset(self) -> Callable[[float], tuple[float, float]]: ...


class CompiledStaticForce:
    """Single-sample closed-form inverse p = (F - B(k)) / A(k) for the tick."""

    __slots__ = ("clipped", "clipped_mask", "input_names", "evaluate")

    def __init__(self, model: ForceMap) -> None:
        self.clipped = False
        self.clipped_mask = 0
        self.input_names = tuple(v.name for v in model.inputs)
        f_lo, f_hi = model.inputs[0].min, model.inputs[0].max
        x_lo, x_hi = model.inputs[1].min, model.inputs[1].max
        p_lo, p_hi = model.output.min, model.output.max
        g_min = MIN_GAIN_N_PER_BAR
        gain_offset_at = model.scalar_gain_offset()

        def evaluate(force_n: float, contraction: float) -> float:
            mask = 0
            if force_n < f_lo:
                force_n, mask = f_lo, 1
            elif force_n > f_hi:
                force_n, mask = f_hi, 1
            if contraction < x_lo:
                contraction, mask = x_lo, mask | 2
            elif contraction > x_hi:
                contraction, mask = x_hi, mask | 2
            gain, offset = gain_offset_at(100.0 * contraction)
            held = False
            if gain > g_min:
                p = (force_n - offset) / gain
            else:
                p, held = p_hi, True
            if p > p_hi:
                p, held = p_hi, True
            elif p < p_lo:
                p, held = p_lo, True
            self.clipped_mask = mask
            self.clipped = mask != 0 or held
            return p

        self.evaluate = evaluate

    def reset(self, *x: float) -> None:
        """Nothing to reset: the model has no state."""


class CompiledForwardForce:
    """Single-sample forward model F = A(k) p + B(k), inputs held to their ranges."""

    __slots__ = ("clipped", "clipped_mask", "input_names", "evaluate")

    def __init__(self, model: ForceMap) -> None:
        self.clipped = False
        self.clipped_mask = 0
        self.input_names = tuple(v.name for v in model.inputs)
        p_lo, p_hi = model.inputs[0].min, model.inputs[0].max
        x_lo, x_hi = model.inputs[1].min, model.inputs[1].max
        gain_offset_at = model.scalar_gain_offset()

        def evaluate(pressure_bar: float, contraction: float) -> float:
            mask = 0
            if pressure_bar < p_lo:
                pressure_bar, mask = p_lo, 1
            elif pressure_bar > p_hi:
                pressure_bar, mask = p_hi, 1
            if contraction < x_lo:
                contraction, mask = x_lo, mask | 2
            elif contraction > x_hi:
                contraction, mask = x_hi, mask | 2
            gain, offset = gain_offset_at(100.0 * contraction)
            self.clipped_mask = mask
            self.clipped = mask != 0
            return gain * pressure_bar + offset

        self.evaluate = evaluate

    def reset(self, *x: float) -> None:
        """Nothing to reset: the model has no state."""

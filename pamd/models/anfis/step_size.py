"""Jang's step-size rule for ANFIS's gradient descent on the premise parameters (as
MATLAB's anfis applies it): grow the step after four consecutive decreases of the
training error, shrink it after two consecutive (increase, decrease) combinations."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class StepSizeState:
    """Step size and the epochs (0-based) of its last increase and decrease."""

    step: float
    last_increase: int = 0
    last_decrease: int = 0


def update_step_size(
    errors: Sequence[float],
    state: StepSizeState,
    increase: float = 1.1,
    decrease: float = 0.9,
) -> StepSizeState:
    """Jang's step-size rule after the error of epoch len(errors) - 1 is known.

    Shrink by `decrease` if the last five errors went up, down, up, down (two
    consecutive increase-decrease combinations); otherwise grow by `increase` if they
    went down four times in a row. Each rule looks only at windows lying after its own
    last firing (at least four epochs apart), so one run of decreases is not counted
    twice. Pure function: returns a new state.
    """
    i = len(errors) - 1
    e = errors
    if i - state.last_decrease >= 4 and (
        e[i - 4] < e[i - 3] and e[i - 3] > e[i - 2] and e[i - 2] < e[i - 1] and e[i - 1] > e[i]
    ):
        return StepSizeState(state.step * decrease, state.last_increase, i)
    if i - state.last_increase >= 4 and (e[i - 4] > e[i - 3] > e[i - 2] > e[i - 1] > e[i]):
        return StepSizeState(state.step * increase, i, state.last_decrease)
    return state

"""Jang's/MATLAB's step-size rule on scripted error sequences (pure function)."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest  # noqa: E402

from pamd.models.anfis.step_size import StepSizeState, update_step_size  # noqa: E402


def run(errors: list[float], step: float = 1.0) -> list[float]:
    """Feed the errors one epoch at a time; the step size after each epoch."""
    state = StepSizeState(step)
    steps = []
    for i in range(len(errors)):
        state = update_step_size(errors[: i + 1], state, increase=1.1, decrease=0.9)
        steps.append(state.step)
    return steps


def test_four_decreases_grow_the_step_once_per_four() -> None:
    steps = run([10, 9, 8, 7, 6, 5, 4, 3, 2])
    # First four decreases complete at epoch index 4; the next window of four *new*
    # decreases completes at index 8 (the windows must not overlap).
    assert steps[:4] == [1.0] * 4
    assert steps[4] == pytest.approx(1.1)
    assert steps[5:8] == [pytest.approx(1.1)] * 3
    assert steps[8] == pytest.approx(1.21)


def test_two_increase_decrease_pairs_shrink_the_step() -> None:
    steps = run([5, 6, 5, 6, 5, 6, 5, 6, 5])
    assert steps[3] == 1.0  # only three changes seen so far
    assert steps[4] == pytest.approx(0.9)  # up, down, up, down
    assert steps[5:8] == [pytest.approx(0.9)] * 3  # guard: 4 epochs since last shrink
    assert steps[8] == pytest.approx(0.81)


def test_other_patterns_leave_the_step_alone() -> None:
    # Three decreases then an increase; down-up-down-up (ends on an increase); flat.
    assert run([4, 3, 2, 1, 2]) == [1.0] * 5
    assert run([6, 5, 6, 5, 6]) == [1.0] * 5
    assert run([1, 1, 1, 1, 1, 1]) == [1.0] * 6
    # Increase, decrease, decrease, decrease: neither rule.
    assert run([1, 2, 1.5, 1.2, 1.1]) == [1.0] * 5


def test_state_is_not_mutated_and_counters_are_epoch_indices() -> None:
    s0 = StepSizeState(0.5)
    s1 = update_step_size([10, 9, 8, 7, 6], s0)
    assert s0 == StepSizeState(0.5)
    assert s1 == StepSizeState(pytest.approx(0.55), last_increase=4, last_decrease=0)
    s2 = update_step_size([1, 2, 1, 2, 1], StepSizeState(0.5), decrease=0.5)
    assert s2.step == 0.25 and s2.last_decrease == 4

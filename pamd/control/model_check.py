"""Whether an inverse model (any kind) can drive a muscle's tick: its inputs must be
signals the tick has, its output a pressure, its ranges must overlap the muscle's
travel, and each kind adds its own checks (`InverseModel.problems`: the rule count of
a fuzzy model, the pressure gain of a force model, ...).

Role: the checks run on a model file before anything compiles it (outside the loop).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from pamd.errors import ModelError
from pamd.models.contract import (
    LENGTH_INPUTS,
    MODEL_OUTPUT,
    SOURCES,
    InverseModel,
    ModelEnvelope,
    velocity_window,
)
from pamd.models.registry import load_model

if TYPE_CHECKING:
    from pamd.config.loader import MuscleLimitsResolved
    from pamd.config.schema import MuscleConfig

__all__ = ["LENGTH_INPUTS", "MODEL_OUTPUT", "SOURCES", "envelope_of", "load_model_for",
           "model_problems", "velocity_window"]


def envelope_of(muscle: MuscleConfig, limits: MuscleLimitsResolved) -> ModelEnvelope:
    """The muscle's travel as a model sees it."""
    return ModelEnvelope(muscle.nominal_length_mm, limits.max_contraction,
                         limits.max_pretension)


def model_problems(model: InverseModel, nominal_length_mm: float, max_contraction: float,
                   max_pretension: float) -> list[str]:
    """Why `model` cannot drive this muscle (empty list: it can)."""
    return model.problems(ModelEnvelope(nominal_length_mm, max_contraction, max_pretension))


def check_model_for(model: InverseModel, source: str, muscle: MuscleConfig,
                    limits: MuscleLimitsResolved) -> InverseModel:
    """`model` if it can drive the muscle; `ModelError` says why not."""
    problems = model.problems(envelope_of(muscle, limits))
    if problems:
        raise ModelError(f"model file {source} cannot drive muscle {muscle.name!r}: "
                         + "; ".join(problems))
    return model


def load_model_for(path: str | os.PathLike[str], muscle: MuscleConfig,
                   limits: MuscleLimitsResolved) -> InverseModel:
    """Load a model file of any kind and check it against a muscle; `ModelError` says
    why not."""
    return check_model_for(load_model(path), str(path), muscle, limits)

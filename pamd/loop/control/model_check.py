"""Whether an inverse model (any kind) can drive a muscle's tick: its inputs must be
signals the tick has, its output a pressure, its ranges must overlap the muscle's
travel, and each kind adds its own checks (`InverseModel.problems`: the rule count of
a fuzzy model, the pressure gain of a force model, ...).

Role: the checks run on a model file before anything compiles it (outside the loop).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from pamd.models.contract import (
    LENGTH_INPUTS,
    MODEL_OUTPUT,
    SOURCES,
    InverseModel,
    ModelEnvelope,
    velocity_window,
)
from pamd.models.domain import Domain, domain_of
from pamd.models.registry import load_model
from pamd.muscle_type.registry import DATASHEET_TYPES, datasheet_type
from pamd.wire.errors import ModelError

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


def _rated_pull_n(muscle: MuscleConfig) -> float | None:
    """The muscle's rated pull (its datasheet type's, or its `custom` section's); None
    where the config does not say (the loader refuses such a config anyway)."""
    if muscle.custom is not None:
        return muscle.custom.theoretical_force_n
    if muscle.type in DATASHEET_TYPES:
        return datasheet_type(muscle.type).theoretical_force_n
    return None


def domain_problems(domain: Domain, muscle: MuscleConfig,
                    limits: MuscleLimitsResolved) -> list[str]:
    """Why a model's training domain cannot meet this muscle at all: an input (or the
    pressure) whose domain lies wholly outside what the muscle can reach (its pressure
    limit, its travel from the contraction limit to the pretension limit, its type's
    theoretical force). Such a model would be off its data on every tick; one that
    overlaps in part runs, and fades where it is off."""
    l0 = muscle.nominal_length_mm
    reach = {"pressure_bar": (0.0, limits.max_pressure_bar),
             "length_mm": (l0 * (1.0 - limits.max_contraction),
                           l0 * (1.0 + limits.max_pretension)),
             "contraction": (-limits.max_pretension, limits.max_contraction)}
    rated_n = _rated_pull_n(muscle)
    if rated_n is not None:
        reach["force_n"] = (0.0, rated_n)
    spans = {c: domain.overall(c) for c in domain.columns}
    if domain.axis is not None:
        spans[domain.axis] = domain.axis_range
    out = []
    for name, (lo, hi) in spans.items():
        if name in reach:
            r_lo, r_hi = reach[name]
            if hi < r_lo or lo > r_hi:
                out.append(f"its training domain's {name} {lo:.4g}..{hi:.4g} lies outside "
                           f"what this muscle reaches ({r_lo:.4g}..{r_hi:.4g})")
    return out


def check_model_for(model: InverseModel, source: str, muscle: MuscleConfig,
                    limits: MuscleLimitsResolved) -> InverseModel:
    """`model` if it can drive the muscle; `ModelError` says why not (its kind's
    problems, a broken or disjoint training domain)."""
    problems = model.problems(envelope_of(muscle, limits))
    if not problems:
        problems = domain_problems(domain_of(model), muscle, limits)
    if problems:
        raise ModelError(f"model file {source} cannot drive muscle {muscle.name!r}: "
                         + "; ".join(problems))
    return model


def load_model_for(path: str | os.PathLike[str], muscle: MuscleConfig,
                   limits: MuscleLimitsResolved) -> InverseModel:
    """Load a model file of any kind and check it against a muscle; `ModelError` says
    why not."""
    return check_model_for(load_model(path), str(path), muscle, limits)

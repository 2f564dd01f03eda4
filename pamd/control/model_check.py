"""Whether an ANFIS model can drive a muscle's tick: its inputs must be signals the
tick has, its output a pressure, its rule count small enough for the tick, its
velocity filter stated, and its training ranges must overlap the muscle's travel.

Role: the checks run on a model file before anything compiles it (outside the loop).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pamd.anfis.model import AnfisModel
from pamd.anfis.modelfile import load
from pamd.errors import ModelError

if TYPE_CHECKING:
    from pamd.config.loader import MuscleLimitsResolved
    from pamd.config.schema import MuscleConfig

#: Signals a model input can be fed from, in the order `Feedforward.pressure` takes them.
SOURCES: tuple[str, ...] = ("force_n", "length_mm", "contraction", "velocity_mm_s")
LENGTH_INPUTS: tuple[str, ...] = ("length_mm", "contraction")
MODEL_OUTPUT = "pressure_bar"
#: Largest rule count accepted for the tick (about 25 us single-sample at 1 kHz; the
#: seeds' layouts are 25 and 27 rules).
MAX_RULES = 125


def model_problems(model: AnfisModel, nominal_length_mm: float, max_contraction: float,
                   max_pretension: float) -> list[str]:
    """Why `model` cannot drive this muscle (empty list: it can)."""
    out = []
    names = [v.name for v in model.inputs]
    if model.output.name != MODEL_OUTPUT:
        out.append(f"its output is {model.output.name!r}, not {MODEL_OUTPUT!r}")
    unknown = [n for n in names if n not in SOURCES]
    if unknown:
        out.append(f"input(s) {', '.join(unknown)} are not signals of the tick (known: "
                   f"{', '.join(SOURCES)})")
    if "force_n" not in names:
        out.append("it has no force_n input")
    lengths = [n for n in names if n in LENGTH_INPUTS]
    if len(lengths) != 1:
        out.append("it needs exactly one of the inputs length_mm or contraction")
    if "velocity_mm_s" in names and velocity_window(model) is None:
        out.append("its velocity_mm_s input does not state its filter (derived_inputs."
                   "velocity_mm_s.window_s, a time constant > 0 s), so the tick cannot "
                   "compute the signal it was trained on")
    if model.n_rules > MAX_RULES:
        out.append(f"{model.n_rules} rules is too many for the tick (at most {MAX_RULES}); "
                   "use fewer membership functions (e.g. 3 on the velocity)")
    lo_mm = nominal_length_mm * (1.0 - max_contraction)
    hi_mm = nominal_length_mm * (1.0 + max_pretension)
    for v in model.inputs:
        if v.name == "length_mm" and (v.max < lo_mm or v.min > hi_mm):
            out.append(f"it was trained on lengths {v.min:.1f}-{v.max:.1f} mm but this muscle "
                       f"moves within {lo_mm:.1f}-{hi_mm:.1f} mm (nominal "
                       f"{nominal_length_mm:g} mm)")
        if v.name == "contraction" and (v.max < -max_pretension or v.min > max_contraction):
            out.append(f"it was trained on contractions {v.min:.3f}-{v.max:.3f} but this "
                       f"muscle moves within {-max_pretension:.3f}-{max_contraction:.3f}")
    return out


def velocity_window(model: AnfisModel) -> float | None:
    """The time constant of the model's velocity input filter (None if not stated)."""
    w = (model.derived_inputs.get("velocity_mm_s") or {}).get("window_s")
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not 0 < w < math.inf:
        return None
    return float(w)


def load_model_for(path: str, muscle: MuscleConfig, limits: MuscleLimitsResolved) -> AnfisModel:
    """Load a model file and check it against a muscle; `ModelError` says why not."""
    model = load(path)
    problems = model_problems(model, muscle.nominal_length_mm, limits.max_contraction,
                              limits.max_pretension)
    if problems:
        raise ModelError(f"model file {path} cannot drive muscle {muscle.name!r}: "
                         + "; ".join(problems))
    return model

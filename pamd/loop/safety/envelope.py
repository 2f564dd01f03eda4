"""A muscle's envelope: everything fixed about what it may do, in one frozen value.

Limits and their bands, the nominal length, the force model, the rate limits and
the inputs of the safe pressure, built once from the config (`from_config`) and
rebuilt when a reload changes them (`with_settings`, IDLE only). The tick, the
command handlers (`pamd.loop.commands`) and the config-time checks
(`pamd.loop.control.length_targets`, `pamd run`) read the same value, so a limit has
one source and one name: the config's.

Not in it: what changes while the rig runs (the hanging load, the measured state),
which the muscle (`pamd.loop.control.muscle.MuscleController`) owns.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

from pamd.config.loader import LoadedConfig, MuscleLimitsResolved
from pamd.config.safety_schema import SafetyConfig
from pamd.config.schema import MuscleConfig
from pamd.loop.safety import safe_pressure_bar
from pamd.loop.safety.length_rate import LengthRate, derive_length_rate
from pamd.loop.safety.load_check import load_tolerance_n
from pamd.muscle_type import ForceModel, MuscleType
from pamd.wire.declare.jsonsafe import JsonObject


@dataclass(frozen=True, slots=True)
class MuscleEnvelope:
    """One muscle's limits, bands, geometry, force model and rate limits (config
    names and units)."""

    name: str
    muscle_type: str  # `muscles[].type`
    rating: MuscleType  # the type resolved: ratings, geometry, force map
    nominal_length_mm: float
    force_model: ForceModel  # the type's, as `muscles[].force_model` names it
    # limits (`pamd.config.loader.MuscleLimitsResolved`)
    max_pressure_bar: float
    hard_max_pressure_bar: float
    max_contraction: float
    hard_max_contraction: float
    max_pretension: float
    hard_max_pretension: float
    # bands
    soft_band_contraction: float
    soft_max_contraction: float  # where the contraction guard starts (limit - band)
    # rate limits
    slew_limit_bar_per_s: float
    safe_slew_bar_per_s: float  # the safe state's ramp (safety.safe_slew_bar_per_s)
    estop_slew_bar_per_s: float
    max_length_rate_per_s: float  # control.position.max_rate_per_s (contraction/s)
    length_rate_origin: str  # what refusals name: the key, or how it was derived
    estop_action: str
    # the safe pressure's inputs (with the load)
    stretch_margin: float
    safe_pressure_margin_bar: float
    # datum checks (`pamd.loop.safety.datums`)
    home_tolerance: float
    tare_tolerance_n: float
    # the declared load's check (`pamd.loop.safety.load_check`)
    dead_weight: bool  # `muscles[].dead_weight`: the load hangs freely, checked at rest
    load_cell_accuracy_n: float
    load_friction_n: float  # safety.plausibility.frozen_force_change_n

    @classmethod
    def build(cls, muscle: MuscleConfig, mtype: MuscleType, limits: MuscleLimitsResolved,
              safety: SafetyConfig, slew_limit_bar_per_s: float,
              max_length_rate_per_s: float | None,
              rate_feedforward_s: float = 0.0) -> MuscleEnvelope:
        """`mtype`: the muscle's type, resolved with its config; `max_length_rate_per_s`
        None: derived (`pamd.loop.safety.length_rate`)."""
        model = mtype.force_model(muscle.force_model)
        origin = "control.position.max_rate_per_s"
        if max_length_rate_per_s is None:
            derived = _derive(muscle, mtype, limits, safety, slew_limit_bar_per_s,
                              rate_feedforward_s)
            max_length_rate_per_s = derived.max_rate_per_s
            origin = f"control.position.max_rate_per_s: null, {derived.explain()}"
        return cls(name=muscle.name, muscle_type=muscle.type, rating=mtype,
                   nominal_length_mm=muscle.nominal_length_mm,
                   force_model=model, dead_weight=muscle.dead_weight,
                   load_cell_accuracy_n=muscle.load_cell_accuracy_n,
                   max_length_rate_per_s=max_length_rate_per_s, length_rate_origin=origin,
                   **_settings(limits, safety, slew_limit_bar_per_s))

    @classmethod
    def from_config(cls, cfg: LoadedConfig, name: str) -> MuscleEnvelope:
        """The envelope of muscle `name` of a validated config."""
        ctl = cfg.control_of(name)
        return cls.build(cfg.muscle(name), cfg.muscle_type(name), cfg.limits[name],
                         cfg.rig.safety,
                         ctl.slew_limit_bar_per_s, ctl.position.max_rate_per_s,
                         ctl.rate_feedforward_s)

    def with_settings(self, limits: MuscleLimitsResolved, safety: SafetyConfig,
                      slew_limit_bar_per_s: float, nominal_length_mm: float) -> MuscleEnvelope:
        """The envelope after a reload's limits, safety, slew and nominal length (the
        muscle type, its force model and the length rate limit stay)."""
        return replace(self, nominal_length_mm=nominal_length_mm,
                       **_settings(limits, safety, slew_limit_bar_per_s))

    @staticmethod
    def derived_length_rate(cfg: LoadedConfig, name: str) -> LengthRate:
        """What `control.position.max_rate_per_s: null` derives for muscle `name`
        (`pamd check-config` prints it)."""
        ctl, m = cfg.control_of(name), cfg.muscle(name)
        return _derive(m, cfg.muscle_type(name), cfg.limits[name], cfg.rig.safety,
                       ctl.slew_limit_bar_per_s, ctl.rate_feedforward_s)

    @property
    def load_tolerance_n(self) -> float:
        """How far the force at rest may stand from the declared load's weight
        (`pamd.loop.safety.load_check.load_tolerance_n`)."""
        return load_tolerance_n(self.load_cell_accuracy_n, self.load_friction_n)

    def contraction(self, length_mm: float) -> float:
        """(nominal - length) / nominal."""
        return (self.nominal_length_mm - length_mm) / self.nominal_length_mm

    def length_mm(self, contraction: float) -> float:
        return self.nominal_length_mm * (1.0 - contraction)

    def safe_pressure_bar(self, load_kg: float) -> float:
        """The safe pressure with `load_kg` hanging (`pamd.loop.safety.safe_pressure_bar`)."""
        return safe_pressure_bar(self.force_model, load_kg, self.max_pretension,
                                 self.stretch_margin, self.safe_pressure_margin_bar,
                                 self.max_pressure_bar)

    def contraction_bounds(self) -> tuple[float, float]:
        """The contraction range a length target may use: inside the soft limits, where
        the tick's limit guards would start to fight the target."""
        return -self.max_pretension + self.soft_band_contraction, self.soft_max_contraction


def _derive(muscle: MuscleConfig, mtype: MuscleType, limits: MuscleLimitsResolved,
            safety: SafetyConfig, slew_limit_bar_per_s: float,
            rate_feedforward_s: float) -> LengthRate:
    """The length rate limit derived for the muscle at its configured load, over its
    contraction range (`contraction_bounds`, from 0 up)."""
    return _derived(
        mtype, muscle.force_model, muscle.load_kg, limits.max_pressure_bar,
        (-limits.max_pretension + safety.soft_band_contraction,
         limits.max_contraction - safety.soft_band_contraction),
        slew_limit_bar_per_s, rate_feedforward_s)


@functools.lru_cache(maxsize=256)
def _derived(mtype: MuscleType, model_name: str, load_kg: float, max_pressure_bar: float,
             contraction_bounds: tuple[float, float], slew_limit_bar_per_s: float,
             rate_feedforward_s: float) -> LengthRate:
    """`derive_length_rate` on the type's named force model, once per set of inputs: it
    is a pure function of them (a datasheet type is one object per process, its map the
    package's data; a custom type is its config load's) and costs ~10 ms of bisections,
    paid at every config load, controller build and reload otherwise."""
    return derive_length_rate(mtype.force_model(model_name), load_kg, max_pressure_bar,
                              contraction_bounds, slew_limit_bar_per_s, rate_feedforward_s)


def _settings(limits: MuscleLimitsResolved, safety: SafetyConfig,
              slew_limit_bar_per_s: float) -> JsonObject:
    """The fields a reload may change (IDLE only), besides the nominal length."""
    return dict(
        max_pressure_bar=limits.max_pressure_bar,
        hard_max_pressure_bar=limits.hard_max_pressure_bar,
        max_contraction=limits.max_contraction, hard_max_contraction=limits.hard_max_contraction,
        max_pretension=limits.max_pretension, hard_max_pretension=limits.hard_max_pretension,
        soft_band_contraction=safety.soft_band_contraction,
        soft_max_contraction=limits.max_contraction - safety.soft_band_contraction,
        slew_limit_bar_per_s=slew_limit_bar_per_s,
        safe_slew_bar_per_s=(slew_limit_bar_per_s if safety.safe_slew_bar_per_s is None
                             else safety.safe_slew_bar_per_s),
        estop_slew_bar_per_s=safety.estop_slew_bar_per_s, estop_action=safety.estop_action,
        stretch_margin=safety.stretch_margin,
        safe_pressure_margin_bar=safety.safe_pressure_margin_bar,
        home_tolerance=safety.home_tolerance, tare_tolerance_n=safety.tare_tolerance_n,
        load_friction_n=safety.plausibility.frozen_force_change_n)

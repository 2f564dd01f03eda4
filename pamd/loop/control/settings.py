"""One muscle's share of a reloaded config (SIGHUP), computed outside the loop's thread
(`pamd.daemon.service.reload`) and handed to the muscle in the `reload` command."""

from __future__ import annotations

from dataclasses import dataclass

from pamd.config.control_schema import PidConfig
from pamd.config.loader import MuscleLimitsResolved
from pamd.config.safety_schema import SafetyConfig


@dataclass(frozen=True, kw_only=True)
class MuscleSettings:
    """One muscle's share of a reloaded config, computed outside the loop's thread
    (`pamd.daemon.service.reload`); the loop only assigns it (`MuscleController.apply_settings`).
    """

    muscle: str
    pid: PidConfig
    rate_feedforward_s: float
    pressure_timeout_s: float
    force_timeout_s: float
    length_timeout_s: float
    safety: SafetyConfig
    limits: MuscleLimitsResolved
    slew_limit_bar_per_s: float
    nominal_length_mm: float
    load_kg: float | None  # None: unchanged in the file (a `load` command's value stays)

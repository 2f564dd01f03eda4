"""The config's `safety` section (the supervisor's limits and timeouts, the sensors'
plausibility thresholds), as frozen dataclasses; `pamd.config.schema` builds the rig's
config from it. The units, bounds and docs here generate docs/config-reference.md."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pamd.wire.schema.engine import spec


@dataclass(frozen=True, kw_only=True)
class PlausibilityConfig:
    enabled: bool = spec(True, "Check every reading for plausibility; an implausible one is a "
                         "fault naming the sensor, and nothing trusts that signal until reset.")
    length_max_rate_mm_s: float = spec(
        2000.0, "A length reading changing faster than this (plus length_jump_mm) between two "
        "samples has jumped: faster than the muscle can move. Over the time between the "
        "samples' stamps plus their declared jitter, never the loop's period.", unit="mm/s",
        gt=0.0)
    length_jump_mm: float = spec(1.0, "Allowance on top of length_max_rate_mm_s (encoder counts, "
                                 "sampling).", unit="mm", min=0.0)
    pressure_max_rate_bar_per_s: float = spec(
        500.0, "A pressure reading changing faster than this (plus pressure_jump_bar) between "
        "two samples has jumped (an exhaust valve vents 6 bar at about 400 bar/s).",
        unit="bar/s", gt=0.0)
    pressure_jump_bar: float = spec(0.3, "Allowance on top of pressure_max_rate_bar_per_s "
                                    "(noise, sampling).", unit="bar", min=0.0)
    min_contraction: float = spec(-0.15, "A length with its datum stretched beyond this "
                                  "contraction is physically impossible (a broken or dead sensor).",
                                  min=-1.0, max=0.0)
    max_contraction: float = spec(0.40, "A length with its datum contracted beyond this (0 "
                                  "mm is 100 %) is physically impossible.", min=0.0, max=1.0)
    frozen_pressure_change_bar: float = spec(
        0.5, "A length that stays within frozen_length_mm while the pressure changes this much, "
        "and the force does not change as it would at a fixed length, is frozen (away from "
        "the stops, the contraction and pretension limits, where it rightly stands).",
        unit="bar", gt=0.0)
    frozen_length_mm: float = spec(0.05, "Length change still counted as not moving.",
                                   unit="mm", min=0.0)
    frozen_force_change_n: float = spec(
        100.0, "What friction can hold the muscle against: a frozen length needs the force "
        "model at that length to change by more than this; a frozen load cell is stuck once "
        "the model at the measured pressure and length moves by more than twice this (a "
        "friction reversal swings it by that while a dead weight's pull stays) or the load's "
        "acceleration says its pull m (g - a) moved by more than this.", unit="N", min=0.0)
    frozen_s: float = spec(0.2, "A force or pressure reading repeating the identical value this "
                           "long where the physics says it changed is frozen: the force "
                           "(frozen_force_change_n), the pressure while the muscle moves "
                           "0.5 mm under its load.",
                           unit="s", gt=0.0)
    force_zero_fraction: float = spec(
        0.2, "A force below this share of the known load's weight for force_zero_s reads zero "
        "under load (checked from force_check_min_load_kg).", min=0.0, max=1.0)
    force_zero_s: float = spec(0.1, "How long a force must read zero under load to fault.",
                               unit="s", gt=0.0)
    force_check_min_load_kg: float = spec(5.0, "Smallest configured load the zero-force check "
                                          "applies to.", unit="kg", min=0.0)


@dataclass(frozen=True, kw_only=True)
class SafetyConfig:
    pressure_margin_bar: float = spec(0.3, "Hard pressure limit = soft limit + this.",
                                      unit="bar", min=0.0, ceiling=1.0, max=3.0)
    contraction_margin: float = spec(0.01, "Hard contraction limit = soft limit + this "
                                     "(fraction).", min=0.0, max=0.2)
    soft_band_contraction: float = spec(0.01, "Within this of the contraction limit the "
                                        "pressure command stops rising (fraction).",
                                        min=0.0, max=0.1)
    hard_limit_hold_s: float = spec(0.02, "A hard limit must be exceeded this long to fault.",
                                    unit="s", min=0.0, ceiling=0.5, max=5.0)
    signal_timeout_s: float = spec(0.05, "A signal older than this is stale and faults.",
                                   unit="s", gt=0.0, ceiling=1.0, max=60.0)
    latency_margin_s: float = spec(0.05, "What a value may age between its device's sample "
                                   "and the tick that reads it (bus transaction, poll "
                                   "thread, a busy host), added to every input's "
                                   "`sample_period_s` (0 where none is stated), the "
                                   "safety chain's too: an input is stale after "
                                   "max(its timeout, sample period + this).", unit="s",
                                   min=0.0, ceiling=0.5, max=5.0)
    tracking_band_bar: float = spec(0.5, "Measured pressure must follow the command within "
                                    "this band ...", unit="bar", gt=0.0, ceiling=1.0,
                                    max=3.0)
    tracking_time_s: float = spec(1.0, "... or the muscle faults after this long (a leak, a "
                                  "dead sensor, no supply).", unit="s", gt=0.0, ceiling=5.0,
                                  max=60.0)
    stretch_margin: float = spec(0.01, "The safe pressure keeps the stretch this far inside "
                                 "the pretension limit (fraction).", min=0.0, max=0.1)
    safe_pressure_margin_bar: float = spec(0.2, "Added to the lowest pressure that holds the "
                                           "load.", unit="bar", min=0.0)
    estop_action: Literal["safe_pressure", "hold", "vent"] = spec(
        "safe_pressure", "Emergency stop: ramp fast to the safe pressure, freeze the present "
        "command, or vent (only honoured where the safe pressure is 0).")
    estop_slew_bar_per_s: float = spec(20.0, "Ramp rate of the emergency action.",
                                       unit="bar/s", gt=0.0)
    safe_slew_bar_per_s: float | None = spec(
        None, "Ramp rate of the safe state (a fault, a stop, a deadman, a start-up outside "
        "the limits): its setpoint moves at most this fast and its command at most this "
        "much per second from the one written when it began. null: the control slew limit "
        "(`control.slew_limit_bar_per_s`). `pamd tune` sets it to the rig's own while its "
        "identification steps use a fast slew limit.", unit="bar/s", gt=0.0, max=100.0)
    startup_timeout_s: float = spec(1.0, "Start-up waits this long for every sensor before "
                                    "faulting.", unit="s", gt=0.0, max=600.0)
    plausibility: PlausibilityConfig = spec(PlausibilityConfig(), "Plausibility checks of "
                                            "the readings (jumps, impossible or frozen values).")
    home_tolerance: float = spec(
        0.03, "`home` is refused when the new length differs by more than this (fraction of "
        "the nominal length) from what the nominal length, the load and the measured pressure "
        "make expected.", min=0.0, max=0.5)
    tare_tolerance_n: float = spec(
        50.0, "`tare` is refused when it would move the force offset by more than this: the "
        "load cell then holds a load nobody declared (use load_kg).", unit="N", min=0.0)
    relax_ceilings: bool = spec(
        False, "Lets the timeouts, bands and margins marked 'relaxed' in this reference go "
        "above their safe ceiling, up to their hard maximum: for rigs whose devices are "
        "slower. Each value over its ceiling is still logged as a warning at every start "
        "and by check-config.")
    relax_stability: bool = spec(
        False, "Lets gains the stability judgement refuses load anyway (a closed pressure "
        "or position loop that is unstable on the stated plant, or with less than its "
        "minimum gain or phase margin: docs/how-to/tune.md, 'Gains judged against "
        "stability'), each logged as a warning at every start and by check-config: for a "
        "rig whose plant cannot be identified with `pamd tune`. State the plant "
        "(`control.plant`) instead wherever it can be measured.")

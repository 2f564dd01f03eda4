"""The simulated rig's scripted faults (the `sim` driver's `faults` option): what can
fail (each fault's `failure`), their defaults, and the rules the per-field bounds cannot catch.

This module deliberately does not use `from __future__ import annotations`, so
`dataclasses.fields(...)[i].type` holds real types for the config engine.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from pamd.wire.schema.engine import spec

#: The failures each signal can have (see `SimFault`).
FAILURES: dict[str, tuple[str, ...]] = {
    "pressure": ("dead", "stuck", "noisy", "jump", "silent"),
    "force": ("dead", "stuck", "noisy", "jump", "silent"),
    "length": ("dead", "stuck", "noisy", "jump", "silent"),
    "supply": ("lost",),
    "valve": ("stuck",),
    "driver": ("error",),
    "loop": ("stall",),
    "safety_chain": ("open", "closed"),
}


@dataclass(frozen=True)
class SimFault:
    """One scripted fault: from `at_s` on, part of the simulated rig fails (until the
    driver's `clear_faults`, e.g. by a test)."""

    at_s: float = spec(0.0, "Time after the driver opened at which the fault starts.", unit="s",
                         min=0.0)
    muscle: str = spec("*", "The muscle it hits ('*' only for the whole driver, signal: driver, "
                     "the loop's process, signal: loop, or the safety chain).")
    signal: Literal["pressure", "force", "length", "supply", "valve", "driver", "loop",
                    "safety_chain"] = spec(
        "driver",
        "What fails: a sensor (pressure, force, length), the air supply (of one muscle, or "
        "with muscle '*' the rig's: the `supply` input reads 0), the regulator (valve), "
        "the whole device (driver), the loop's process (loop) or the hardware safety "
        "chain (safety_chain, muscle '*').",
    )
    failure: Literal["dead", "stuck", "noisy", "jump", "silent", "lost", "error", "stall",
                  "open", "closed"] = spec(
        "error",
        "Sensors: dead (reads 0), stuck (repeats its last value), noisy (adds noise of "
        "standard deviation `size`), jump (steps by `size` and stays), silent (no new "
        "samples); supply: lost; valve: stuck (the regulator ignores new setpoints); "
        "driver: error (readings stop, writes dropped); loop: stall (the loop's process "
        "stops for `duration_s`, once: the tick holds Python's interpreter lock, so no "
        "thread of the process runs, as when the process gets no CPU; needs the real "
        "clock, a virtual one does not move meanwhile); safety_chain: open (an e-stop "
        "pressed: the chain's input reads 0 and the chain cuts the supply of every "
        "muscle) or closed (released again: the air returns).",
        old="kind",
    )
    duration_s: float | None = spec(
        None, "stall: how long the loop's process stops (required there, refused "
        "elsewhere). Past the loop's stall fault limit (`loop.stall_fault_s`, derived "
        "from the actuation) it latches FAULT; a shorter one is a `stall` event.",
        unit="s", gt=0.0, max=10.0)
    size: float | None = spec(
        None,
        "noisy: noise standard deviation; jump: step; in the signal's unit (default: 0.3 "
        "bar, 50 N, 5 mm for noisy; 1 bar, 200 N, 20 mm for jump).",
    )


#: Default `size` of a noisy / jump fault per sensor.
NOISE_DEFAULT = {"pressure": 0.3, "force": 50.0, "length": 5.0}
JUMP_DEFAULT = {"pressure": 1.0, "force": 200.0, "length": 20.0}


def check_faults(faults: Sequence[SimFault], names: Sequence[str]) -> list[str]:
    """Problems of a fault schedule on a rig of muscles `names`, as sentences."""
    problems: list[str] = []
    for k, f in enumerate(faults):
        where = f"faults[{k}]"
        if f.failure not in FAILURES[f.signal]:
            problems.append(
                f"{where}: a {f.signal} fault is one of {', '.join(FAILURES[f.signal])}, "
                f"not {f.failure!r}"
            )
        problems += _muscle_problems(f, names, where)
        if (f.failure == "stall") != (f.duration_s is not None):
            problems.append(f"{where}: duration_s is " + (
                "required by a stall (how long the loop's process stops)"
                if f.failure == "stall" else f"only for a stall, not a {f.failure} fault"))
        problems += _size_problems(f, where)
    return problems


def _muscle_problems(f: SimFault, names: Sequence[str], where: str) -> list[str]:
    """The fault's muscle: '*' for the loop and the safety chain (the rig's), '*' or a
    muscle for a driver or the supply, a muscle of this sim driver for a signal."""
    if f.signal == "loop":
        if f.muscle != "*":
            return [f"{where}: a loop stall stops the whole process: muscle "
                    f"'*', not {f.muscle!r}"]
    elif f.signal in ("driver", "supply", "safety_chain"):
        if f.signal == "safety_chain" and f.muscle != "*":
            return [f"{where}: the safety chain is the rig's: muscle '*'"]
        if f.muscle not in ("*", *names):
            return [f"{where}: no muscle {f.muscle!r} (muscles: {', '.join(names)})"]
    elif f.muscle not in names:
        return [f"{where}: no muscle {f.muscle!r} in this sim driver (muscles: "
                f"{', '.join(names)}); a {f.signal} fault names its muscle"]
    return []


def _size_problems(f: SimFault, where: str) -> list[str]:
    """The fault's size: finite (and > 0 for noisy), not 0 for a jump, and given for
    noisy and jump faults only."""
    if f.size is not None and (not math.isfinite(f.size) or
                               (f.failure == "noisy" and f.size <= 0.0)):
        return [f"{where}: size must be finite (and > 0 for noisy), got {f.size}"]
    if f.failure == "jump" and f.size == 0.0:
        return [f"{where}: a jump of size 0 changes nothing: no fault to script"]
    if f.size is not None and f.failure not in ("noisy", "jump"):
        return [f"{where}: size applies to noisy and jump faults only, not {f.failure!r}"]
    return []

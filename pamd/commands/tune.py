"""The tuning commands, in the loop's thread: `relay`, the relay-feedback test of one
muscle's pressure loop (`pamd.control.relay`). Internal: `pamd tune --method relay`
queues it through its own daemon; no client can send it."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from pamd.commands.guards import can_move, named_muscles
from pamd.commands.motion import VERBS as MOTION_VERBS
from pamd.commands.registry import Verb
from pamd.controller import RigController
from pamd.declare.jsonsafe import JsonObject
from pamd.errors import CommandRefused
from pamd.verbs.schema import SetpointArgs
from pamd.verbs.table import VerbSpec


@dataclass(frozen=True)
class RelayArgs:
    """The relay test around `center_bar`: the setpoint ramps there (as a `setpoint`
    command does), holds `hold_s`, then the relay runs (all in loop time: the same
    every run on the virtual clock)."""

    muscle: str
    center_bar: float = dataclasses.field(metadata={"unit": "bar"})
    amplitude_bar: float = dataclasses.field(metadata={"unit": "bar"})
    hysteresis_bar: float = dataclasses.field(metadata={"unit": "bar"})
    max_amplitude_bar: float = dataclasses.field(metadata={"unit": "bar"})
    cycles: int = 8
    timeout_s: float = 2.0
    settle_s: float = 0.2
    hold_s: float = 0.5


def _relay(ctrl: RigController, a: RelayArgs) -> JsonObject:
    can_move(ctrl)
    m = named_muscles(ctrl, a.muscle)[0]
    if m.in_length_mode:
        raise CommandRefused(f"{m.name}: the relay test runs in pressure mode")
    center = a.center_bar
    env = m.envelope
    low = env.safe_pressure_bar(m.load_kg)
    if not 0.0 < a.amplitude_bar <= a.max_amplitude_bar:
        raise CommandRefused(f"{m.name}: a relay amplitude of {a.amplitude_bar:g} bar is not "
                             f"allowed: above 0 and at most {a.max_amplitude_bar:g} bar")
    if not 0.0 <= a.hysteresis_bar < a.amplitude_bar:
        raise CommandRefused(f"{m.name}: the relay's hysteresis ({a.hysteresis_bar:g} bar) "
                             f"must be below its amplitude ({a.amplitude_bar:g} bar)")
    if center - a.amplitude_bar < low or center + a.amplitude_bar > env.max_pressure_bar:
        raise CommandRefused(f"{m.name}: {center:g} +/- {a.amplitude_bar:g} bar leaves "
                             f"{low:.2f}-{env.max_pressure_bar:g} bar (safe pressure to "
                             "pressure limit)")
    ramp = _SETPOINT.handler(ctrl, SetpointArgs(muscle=m.name, bar=center))
    m.pressure_loop.relay.start(center, a.amplitude_bar, a.hysteresis_bar, a.cycles,
                                a.timeout_s, a.settle_s, a.hold_s)
    return {"muscle": m.name, "center_bar": center, "amplitude_bar": a.amplitude_bar,
            "ramp_s": (ramp or {}).get("ramp_s")}


_SETPOINT = next(v for v in MOTION_VERBS if v.name == "setpoint")


VERBS: tuple[Verb, ...] = (
    Verb(VerbSpec("relay", RelayArgs, "the relay-feedback test of a muscle's pressure loop "
                  "(pamd tune --method relay)", internal=True), _relay),
)

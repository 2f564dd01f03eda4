"""The tuning commands, in the loop's thread: `relay`, the relay-feedback test of one
muscle's pressure loop (`pamd.loop.control.relay`), and `pulse`, a timed pulse of one
on/off valve (`pamd.loop.control.valve_pulse`). Internal: `pamd tune --method relay` and
`pamd tune --loop onoff` queue them through their own daemon; no client can send
them."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

from pamd.loop.commands.guards import can_move, named_muscles
from pamd.loop.commands.motion_verbs import VERBS as MOTION_VERBS
from pamd.loop.commands.verb_registry import Verb
from pamd.loop.control.actuation import OnOffActuation
from pamd.loop.control.controller import RigController
from pamd.loop.control.onoff import EXHAUST, INFLATE
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.verbs.args import SetpointArgs
from pamd.wire.verbs.table import VerbSpec


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

#: an on/off muscle's valves, by their signal names
Valve = Literal["inflate", "exhaust"]

#: the longest valve pulse the `pulse` command opens (s): the step test's longest is
#: 0.3 s; an on/off valve open longer moves a DMSP-20 by a bar or more
MAX_PULSE_S = 0.5
#: the longest hold before or after a pulse (s)
MAX_REST_S = 5.0


@dataclass(frozen=True)
class PulseArgs:
    """One valve of an on/off muscle open for `pulse_s`, both shut `rest_s` before and
    `after_s` after (loop time)."""

    muscle: str
    valve: Valve
    pulse_s: float = dataclasses.field(metadata={"unit": "s"})
    rest_s: float = dataclasses.field(default=0.05, metadata={"unit": "s"})
    after_s: float = dataclasses.field(default=0.25, metadata={"unit": "s"})


def _pulse(ctrl: RigController, a: PulseArgs) -> JsonObject:
    """Check the pulse against the muscle's valves and limits, then arm it (the tick
    opens the valve: `pamd.loop.control.valve_pulse`)."""
    can_move(ctrl)
    m = named_muscles(ctrl, a.muscle)[0]
    act = m.actuation
    if not isinstance(act, OnOffActuation):
        raise CommandRefused(f"{m.name}: a valve pulse opens on/off valves; this muscle has "
                             "a pressure regulator (actuation: proportional)")
    if m.in_length_mode:
        raise CommandRefused(f"{m.name}: a valve pulse runs in pressure mode (send mode "
                             "pressure first)")
    if act.pulse.active:
        raise CommandRefused(f"{m.name}: a valve pulse is running; wait for its end")
    shortest = act.pulser.min_pulse_s
    if not shortest - 1e-9 <= a.pulse_s <= MAX_PULSE_S:
        raise CommandRefused(f"{m.name}: a {1e3 * a.pulse_s:g} ms pulse is not allowed: from "
                             f"{1e3 * shortest:g} ms (shorter never moves the valve's spool) "
                             f"to {1e3 * MAX_PULSE_S:g} ms")
    if not (0.0 <= a.rest_s <= MAX_REST_S and 0.0 <= a.after_s <= MAX_REST_S):
        raise CommandRefused(f"{m.name}: the holds before and after a pulse are from 0 to "
                             f"{MAX_REST_S:g} s")
    p = m.pressure_bar
    if not m.inputs.pressure_ok or p != p:
        raise CommandRefused(f"{m.name}: no trusted pressure: a valve pulse needs one")
    low, high = m.safe_pressure_bar, m.envelope.max_pressure_bar
    if a.valve == "inflate" and p + act.fill_rate * a.pulse_s > high:
        raise CommandRefused(f"{m.name}: a {1e3 * a.pulse_s:g} ms inflate pulse from "
                             f"{p:.2f} bar would pass the pressure limit {high:g} bar (at "
                             f"fill_rate_bar_per_s {act.fill_rate:g}): lower the pressure "
                             "first or pulse shorter")
    if a.valve == "exhaust" and p - act.vent_rate * a.pulse_s < low:
        raise CommandRefused(f"{m.name}: a {1e3 * a.pulse_s:g} ms exhaust pulse from "
                             f"{p:.2f} bar would vent below the safe pressure {low:.2f} bar "
                             f"(at vent_rate_bar_per_s {act.vent_rate:g}): raise the "
                             "pressure first or pulse shorter")
    act.pulse.start(INFLATE if a.valve == "inflate" else EXHAUST, a.pulse_s, a.rest_s,
                    a.after_s, low, high)
    return {"muscle": m.name, "valve": a.valve, "pulse_s": a.pulse_s,
            "t_s": ctrl.now - ctrl.t_start}


VERBS: tuple[Verb, ...] = (
    Verb(VerbSpec("relay", RelayArgs, "the relay-feedback test of a muscle's pressure loop "
                  "(pamd tune --method relay)", internal=True), _relay),
    Verb(VerbSpec("pulse", PulseArgs, "a timed pulse of one on/off valve (pamd tune --loop "
                  "onoff)", internal=True), _pulse),
)

"""The `pulse` command (`pamd tune --loop onoff`'s step test) on a simulated on/off
muscle: checked against the valves and the limits before a valve opens, then timed in
the tick (whole ticks, both valves shut around it), ended early with the reason when
the command moves or the pressure reaches the limit."""

from __future__ import annotations

from typing import Any, Literal

import pytest

from pamd.loop.commands.tune_verbs import PulseArgs
from pamd.loop.control.actuation import OnOffActuation
from pamd.loop.control.relay import DONE
from pamd.loop.control.valve_pulse import AT_LIMIT, MOVED
from pamd.loop.harness import Harness
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import Flag
from pamd.wire.verbs.args import Command
from tests.safety.conftest import onoff_muscles, sim_driver

INFLATE, EXHAUST = int(Flag.INFLATE_OPEN), int(Flag.EXHAUST_OPEN)


def pulse(h: Harness, valve: Literal["inflate", "exhaust"], pulse_s: float,
          rest_s: float = 0.05, after_s: float = 0.25) -> JsonObject:
    """Queue a pulse as `pamd tune` does (an internal verb: no client sends it) and take
    it at the next tick; its verdict."""
    verdicts: list[JsonObject] = []
    h.queue.waiting.append(Command("pulse", PulseArgs("m1", valve, pulse_s, rest_s, after_s),
                                   verdicts.append))
    h.step(h.period_s)
    return verdicts[0]


def at(harness: Any, bar: float, load_kg: float = 30.0,
       settings: dict[str, float] | None = None) -> Harness:
    """An on/off muscle (`settings`: its `onoff` section) holding `bar`."""
    muscle = {**onoff_muscles(load_kg)[0], "onoff": settings or {}}
    h: Harness = harness(load_kg, drivers=sim_driver(load_kg, 0.0, None, "onoff"),
                         muscles=[muscle])
    h.step(0.01)
    assert h.cmd("setpoint", muscle="m1", bar=bar)["ok"]
    h.step(3.0)
    return h


def onoff(h: Harness) -> OnOffActuation:
    act = h.m1.actuation
    assert isinstance(act, OnOffActuation)
    return act


def test_a_pulse_opens_one_valve_for_whole_ticks_between_two_rests(harness: Any) -> None:
    h = at(harness, 3.0)
    p0 = h.m1.pressure_bar
    h.keep = True
    v = pulse(h, "inflate", 0.04, rest_s=0.05, after_s=0.1)
    assert v["ok"] and v["valve"] == "inflate", v
    h.step(0.25)
    flags = [int(r["m1"]["flags"]) for r in h.records]
    opened = [i for i, f in enumerate(flags) if f & INFLATE]
    assert len(opened) == 40 and opened == list(range(opened[0], opened[0] + 40))
    assert opened[0] == 50  # after 50 ticks (rest_s) with both valves shut
    assert not any(f & EXHAUST for f in flags)  # the PWM left the valves to it
    assert onoff(h).pulse.outcome == DONE and not onoff(h).pulse.active
    assert h.m1.pressure_bar - p0 > 0.1  # 40 ms of the inflate valve


def test_a_moved_setpoint_stops_the_pulse(harness: Any) -> None:
    h = at(harness, 3.0)
    h.keep = True
    assert pulse(h, "inflate", 0.3, rest_s=0.0)["ok"]
    h.step(0.05)
    assert h.cmd("setpoint", muscle="m1", bar=2.8)["ok"]
    h.step(0.01)
    assert onoff(h).pulse.outcome == MOVED
    assert sum(1 for r in h.records if int(r["m1"]["flags"]) & INFLATE) < 60  # not 300


def test_the_tick_shuts_the_valve_at_the_pressure_limit(harness: Any) -> None:
    """A fill rate in the config far below the valve's: the command's prediction lets
    the pulse pass, the tick sees the pressure reach the limit and shuts the valve."""
    h = at(harness, 5.6, settings={"fill_rate_bar_per_s": 0.5})
    assert pulse(h, "inflate", 0.5, rest_s=0.0, after_s=0.0)["ok"]
    h.step(0.6)
    assert onoff(h).pulse.outcome == AT_LIMIT
    assert h.m1.pressure_bar < 6.2 and h.state == "RUNNING"


@pytest.mark.parametrize(("bar", "load_kg", "valve", "pulse_s", "after_s", "said"), [
    (3.0, 30.0, "inflate", 0.6, 0.25, "a 600 ms pulse is not allowed: from 6 ms"),
    (3.0, 30.0, "exhaust", 0.002, 0.25, "a 2 ms pulse is not allowed"),
    (3.0, 30.0, "inflate", 0.04, 9.0, "from 0 to 5 s"),
    (5.5, 30.0, "inflate", 0.3, 0.25, "would pass the pressure limit 6 bar"),
    (2.0, 80.0, "exhaust", 0.3, 0.25, "would vent below the safe pressure 1.58"),
])
def test_a_pulse_past_the_limits_is_refused(harness: Any, bar: float, load_kg: float,
                                            valve: Literal["inflate", "exhaust"],
                                            pulse_s: float, after_s: float, said: str) -> None:
    h = at(harness, bar, load_kg)
    switches = onoff(h).switch_count
    v = pulse(h, valve, pulse_s, after_s=after_s)
    assert not v["ok"] and said in str(v["error"]), v
    h.step(0.1)
    assert not onoff(h).pulse.active and onoff(h).pulse.outcome == ""
    assert onoff(h).switch_count - switches <= 2  # the PWM's own pulses at most


def test_a_pulse_is_refused_on_a_regulator_and_while_one_runs(harness: Any) -> None:
    h = harness(30.0)
    h.step(0.01)
    v = pulse(h, "inflate", 0.04)
    assert not v["ok"] and "this muscle has a pressure regulator" in str(v["error"])
    h = at(harness, 3.0)
    assert pulse(h, "inflate", 0.04)["ok"]
    v = pulse(h, "exhaust", 0.04)
    assert not v["ok"] and "a valve pulse is running" in str(v["error"])

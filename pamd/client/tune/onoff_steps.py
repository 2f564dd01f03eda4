"""`pamd tune --loop onoff`: the step test of a muscle on on/off valves, its analysis
from the recording and the rules that turn it into `muscles[].onoff` settings (the
PWM pressure loop's and seed 004's sliding mode's), never from the simulator's
parameters, only from what the sensors saw.

The step test (`pamd.client.tune.onoff_run` runs it through the daemon; bench/tune_onoff.py
the same pulses on the in-process harness) is an *identification run*: the PWM's dead
band opened to 1 bar, so it leaves the valves to the pulses once the muscle holds the
level (`LEVEL_BAR`, 3 bar, for `SETTLE_S`). Then each valve in turn, inflate then
exhaust, one timed pulse at a time (the `pulse` command: both valves shut `WINDOW_S`
before and 0.2 s + `WINDOW_S` after), the pressure wandering from pulse to pulse:

1. a 40 ms pulse: the pressure step over the pulse's recorded length is the valve's rate
   (`fill_rate_bar_per_s`, `vent_rate_bar_per_s`; the duty's gain);
2. the shortest pulse the PWM sends (`pamd.loop.control.actuation.min_pulse_s`),
   `SHORTEST_REPEATS` (3) times per valve, inflate and exhaust alternating (the
   pressure stays within a few steps of the level): half the smaller of the two
   valves' typical steps (`typical_step_bar`: the mean of the repeats `counted`) is
   `dead_band_bar` (no pulse can place the pressure closer); the smallest length
   change seen is the encoder's count. One such pulse's step is not the valve's: its
   spool's switching delays, not the tick, decide how long it is really open, and they
   vary from pulse to pulse. Measured on the real clock (a loaded 2-core PC, 42 runs,
   20 beside two CPU hogs): every shortest pulse recorded 6 ticks, 6.0 ms between the
   ticks that opened and shut it, the means' noise ~0.5 mbar of a 30-50 mbar step; but
   the simulated spool was open 7, 8 or 9 ms for it, and one pulse's step scatters 8 %
   (sd) from the next: the first pair's dead band spread 0.0124-0.0165 bar (sd 7.2 %),
   the mean of three's 0.0131-0.0157 (sd 4.9 %). A repeat is left out when the
   recording shows it longer than the PWM's shortest (a tick skipped near its end kept
   the valve open a tick more) or its step beyond `OUTLIER_FRACTION` of the others'
   median (held open by a stall, or cut); a valve with none left is refused;
3. a 300 ms pulse: the fastest length change seen (over 50 ms) is the valve's speed
   on the muscle, held open (the muscle reaches it within about 0.2 s; a 150 ms pulse
   measured the exhaust at half its speed, issue 29). The *faster* of the two valves
   sets the boundary layer (`position_boundary_mm_s`): the duty s / boundary is then a
   velocity feedback of gain (valve speed / boundary) <= 1 for both valves. With the
   boundary at the slower valve's underestimated speed (14.2 mm/s against 43 and 31
   mm/s) the gain was 2-3, the surface left the layer at every swing and the valves
   relayed fully open against the hanging load's oscillation: the +-2 mm hunting of
   issue 29. `position_lambda_per_s` = boundary / 3 mm puts the layer's edge 3 mm from
   a target at rest (chosen on issue 14's single 10 mm step from 3 bar at 30 kg, not
   on issue 29's plateaus: 5 mm left that step 0.22 mm short after 6 s, the last
   creep pulses too small for the stuck muscle; 1 mm relays most of a 5 mm step);
   `position_hold_band_mm` is one encoder count.

`response_s` is 5 PWM periods (the PWM averages over a few). A pulse's recorded length
is the loop time from the tick that opened its valve to the one that shut it (a tick
a busy PC skipped leaves no sample, but its time passed). Each pressure and length
before and after a pulse is the mean over `WINDOW_S` (50 samples at 1 kHz), with both
valves shut, so sensor noise averages out: before, right before the valve opens;
after, from 0.2 s after it shut. The speeds are read from the valve's opening to then
(0.5 s after the 300 ms pulses measured the same speeds, and left the pressure 1.3
bar above the command long enough for the tracking check, 1 s, on the real clock).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from pamd.client.tune.ident_run import TuneRefused
from pamd.client.tune.yamledit import change_row
from pamd.loop.commands.tune_verbs import Valve
from pamd.wire.tick import Flag

LEVEL_BAR = 3.0
SETTLE_S = 2.0  # the PWM holding the level before the first pulse
#: the identification run's PWM dead band (bar): the PWM holds once the level is
#: reached and leaves the valves to the pulses
IDENT_DEAD_BAND_BAR = 1.0
RATE_PULSE_S = 0.04
SPEED_PULSE_S = 0.3
SPEED_WINDOW_S = 0.05  # a speed over 50 ms: 0.2 mm/s per encoder count
WINDOW_S = 0.05  # the mean before and after a pulse
LAYER_MM = 3.0  # the boundary layer's edge from a target at rest
RESPONSE_PERIODS = 5.0
#: the PWM's shortest pulse, per valve (their typical step sets the dead band): each
#: costs ~0.3 s of rig time
SHORTEST_REPEATS = 3
#: a shortest pulse's step this far from its repeats' median (relative) is left out of
#: the typical step: the spool's own scatter reaches 9 against 7 ms of flow (+29 %); a
#: pulse beyond half again (or half) the others' was held open by a stall or cut short
OUTLIER_FRACTION = 0.5
#: a pulse's pressure step smaller than this moved nothing (bar): the mean of 50
#: samples resolves a few mbar
MIN_STEP_BAR = 0.002
#: a 300 ms pulse that moved the length less than this moved nothing (mm)
MIN_LENGTH_MM = 0.1

INFLATE_OPEN, EXHAUST_OPEN = int(Flag.INFLATE_OPEN), int(Flag.EXHAUST_OPEN)


SETTLE_AFTER_S = 0.2  # after a pulse, before the mean after it
#: both valves shut after a pulse (the `pulse` command's `after_s`): settle, then the mean
AFTER_S = SETTLE_AFTER_S + WINDOW_S


@dataclass(frozen=True)
class Pulse:
    """One pulse of the step test (`pulse_s` None: the PWM's shortest)."""

    valve: Valve
    pulse_s: float | None

    def length_s(self, shortest_s: float) -> float:
        return shortest_s if self.pulse_s is None else self.pulse_s


PULSES = (Pulse("inflate", RATE_PULSE_S), Pulse("exhaust", RATE_PULSE_S),
          *(Pulse(valve, None) for _ in range(SHORTEST_REPEATS)
            for valve in ("inflate", "exhaust")),
          Pulse("inflate", SPEED_PULSE_S), Pulse("exhaust", SPEED_PULSE_S))
"""The step test, in order: the shortest pulses alternate inflate and exhaust, so the
pressure wanders by one step around the level, not three steps away from it."""
N_RATE, N_SHORTEST = 2, 2 * SHORTEST_REPEATS


@dataclass(frozen=True, eq=False)
class PulseTrace:
    """The recording around one pulse, as measured (`pamd.client.tune.onoff_plot` draws it):
    from `WINDOW_S` before the mean before to `WINDOW_S` after the mean after, times
    from the valve's opening; where the means were taken and what they were; where the
    fastest length change began."""

    t_s: np.ndarray  # from the valve's opening
    pressure_bar: np.ndarray
    length_mm: np.ndarray
    after_from_s: float  # the mean after: WINDOW_S from here (before: the WINDOW_S before 0)
    pressure_before_bar: float
    length_before_mm: float
    fastest_from_s: float  # the fastest length change: SPEED_WINDOW_S from here


@dataclass(frozen=True)
class PulseResponse:
    """What one pulse did: the pressure and length steps, the fastest length change."""

    pulse: Pulse
    pulse_s: float  # as recorded: from the tick that opened the valve to the one that shut it
    off_by_s: float  # pulse_s less the commanded length (whole ticks)
    pressure_step_bar: float
    length_step_mm: float
    speed_mm_s: float
    trace: PulseTrace = field(compare=False, repr=False)


@dataclass(frozen=True)
class StepTest:
    """The step test's measurements (inflate first in each pair; the shortest pulses
    alternating, inflate first, `SHORTEST_REPEATS` of each valve)."""

    rate: tuple[PulseResponse, PulseResponse]
    shortest: tuple[PulseResponse, ...]
    speed: tuple[PulseResponse, PulseResponse]
    count_mm: float  # the smallest length change seen

    @classmethod
    def of(cls, r: list[PulseResponse], count_mm: float) -> StepTest:
        """The step test from its responses in the order they ran (`PULSES`)."""
        k = N_RATE + N_SHORTEST
        return cls((r[0], r[1]), tuple(r[N_RATE:k]), (r[k], r[k + 1]), count_mm)

    def responses(self) -> tuple[PulseResponse, ...]:
        """The pulses, in the order they ran (`PULSES`)."""
        return (*self.rate, *self.shortest, *self.speed)


class Measurement(NamedTuple):
    """One pulse as the rules take it."""

    pulse: Pulse
    pressure_step_bar: float  # signed
    speed_mm_s: float  # the fastest length change
    off_by_s: float = 0.0  # the recorded length less the commanded one (whole ticks)


def shortest_of(measured: Sequence[Measurement], valve: Valve) -> list[Measurement]:
    """One valve's shortest pulses, in the order they ran."""
    return [m for m in measured if m.pulse.valve == valve and m.pulse.pulse_s is None]


def counted(repeats: Sequence[Measurement]) -> list[bool]:
    """Which of one valve's shortest pulses the typical step counts. Not one the
    recording shows longer (or shorter) than the PWM's shortest: a tick skipped by a
    busy PC near its end kept the valve open a whole tick more (7 against 6 ms), which
    is not the pulse the dead band is about. Of the rest, those within
    `OUTLIER_FRACTION` of their median (the median itself always): the spool's switching
    delays scatter the steps (on the simulated rig by 1 ms of its 8 ms of flow, +-12 %;
    7 against 9 ms is +29 %) and the level's drift by a few %; a step beyond that was
    not the PWM's shortest pulse either."""
    timed = [abs(m.off_by_s) < 1e-9 for m in repeats]
    steps = [m.pressure_step_bar for m, ok in zip(repeats, timed, strict=True) if ok]
    if not steps:
        return timed
    median = float(np.median(np.asarray(steps, dtype=float)))
    return [ok and abs(m.pressure_step_bar - median) <= OUTLIER_FRACTION * abs(median)
            for m, ok in zip(repeats, timed, strict=True)]


def typical_step_bar(repeats: Sequence[Measurement]) -> float:
    """One valve's typical shortest-pulse step (bar, signed): the mean of its repeats
    that `counted` keeps (NaN: none; `check` refuses that). The mean, not the median:
    the steps scatter about evenly (the spool open a plant step shorter or longer), and
    the mean of three spreads 4.7 % over the real clock's runs, the median of three 6 %
    (resampled from 39 measured steps)."""
    kept = [m.pressure_step_bar for m, ok in zip(repeats, counted(repeats), strict=True)
            if ok]
    return float(np.mean(np.asarray(kept, dtype=float))) if kept else float("nan")


def derive(measured: Sequence[Measurement], count_mm: float,
           pwm_period_s: float) -> dict[str, float]:
    """The rules applied to the pulses as measured (the daemon's step test and
    bench/tune_onoff.py's alike): the rate and speed pulses' steps and speeds, each
    valve's typical shortest-pulse step."""
    def one(valve: Valve, pulse_s: float) -> Measurement:
        [m] = [m for m in measured if m.pulse == Pulse(valve, pulse_s)]
        return m

    def rate_step(valve: Valve) -> float:
        """The rate pulse's step over `RATE_PULSE_S`: a pulse the recording shows a tick
        longer (a skipped tick near its end) is scaled back by its recorded length, as
        over 40 ms the valve's flow barely changes (the pressure moves ~0.2 bar of the
        supply's 6), so the step grows with the time open (2.5 % a tick)."""
        m = one(valve, RATE_PULSE_S)
        return m.pressure_step_bar * RATE_PULSE_S / (RATE_PULSE_S + m.off_by_s)

    return settings(rate_step("inflate"), rate_step("exhaust"),
                    typical_step_bar(shortest_of(measured, "inflate")),
                    typical_step_bar(shortest_of(measured, "exhaust")),
                    one("inflate", SPEED_PULSE_S).speed_mm_s,
                    one("exhaust", SPEED_PULSE_S).speed_mm_s, count_mm, pwm_period_s)


def settings(fill_step_bar: float, vent_step_bar: float, fill_min_bar: float,
             vent_min_bar: float, fill_speed_mm_s: float, vent_speed_mm_s: float,
             count_mm: float, pwm_period_s: float) -> dict[str, float]:
    """The rules (the module's docstring): `muscles[].onoff` from the step test's
    pressure steps (bar, signed), valve speeds and encoder count."""
    boundary = max(fill_speed_mm_s, vent_speed_mm_s)  # velocity gain <= 1 for both valves
    return {
        "fill_rate_bar_per_s": fill_step_bar / RATE_PULSE_S,
        "vent_rate_bar_per_s": -vent_step_bar / RATE_PULSE_S,
        "response_s": RESPONSE_PERIODS * pwm_period_s,
        "dead_band_bar": 0.5 * min(abs(fill_min_bar), abs(vent_min_bar)),
        "position_lambda_per_s": boundary / LAYER_MM,
        "position_boundary_mm_s": boundary,
        "position_hold_band_mm": count_mm,
    }


def derived_settings(test: StepTest, pwm_period_s: float) -> dict[str, float]:
    """The rules applied to the step test."""
    return derive(measurements(test), test.count_mm, pwm_period_s)


def measurements(test: StepTest) -> list[Measurement]:
    """The step test's pulses as the rules take them."""
    return [Measurement(r.pulse, r.pressure_step_bar, r.speed_mm_s, r.off_by_s)
            for r in test.responses()]


def fastest(length_mm: np.ndarray, dt_s: float) -> tuple[float, int]:
    """The fastest length change over SPEED_WINDOW_S in a trace sampled every `dt_s`
    (mm/s), and the sample its window begins at."""
    w = round(SPEED_WINDOW_S / dt_s)
    if len(length_mm) <= w:
        return 0.0, 0
    change = np.abs(length_mm[w:] - length_mm[:-w])
    k = int(np.argmax(change))
    return float(change[k]) / SPEED_WINDOW_S, k


def smallest_change_mm(length_mm: np.ndarray) -> float:
    """The smallest nonzero change between two samples (the encoder's count); 0: none."""
    steps = np.unique(np.round(np.abs(np.diff(length_mm)), 6))
    steps = steps[steps > 0.0]
    return float(steps[0]) if steps.size else 0.0


def response(t_s: np.ndarray, p_bar: np.ndarray, l_mm: np.ndarray, flags: np.ndarray,
             pulse: Pulse, sent_s: float, shortest_s: float) -> tuple[PulseResponse, slice]:
    """One pulse's response in the recording: the ticks its valve was open at or after
    `sent_s` (where the command was taken), the means before and after; and the span
    of the ticks measured."""
    dt = float(np.median(np.diff(t_s)))
    n_w = round(WINDOW_S / dt)
    bit = INFLATE_OPEN if pulse.valve == "inflate" else EXHAUST_OPEN
    want = pulse.length_s(shortest_s)
    start = int(np.searchsorted(t_s, sent_s - 0.5 * dt))
    end = int(np.searchsorted(t_s, sent_s + WINDOW_S + want + AFTER_S + 2 * dt))
    open_i = start + np.nonzero(flags[start:end].astype(np.int64) & bit)[0]
    if open_i.size == 0:
        raise TuneRefused(f"the {pulse.valve} pulse sent at {sent_s:.3f} s is not in the "
                          "recording (its valve never open): the recording is incomplete")
    i0, i1 = int(open_i[0]), int(open_i[-1]) + 1
    if i1 >= len(t_s):
        raise TuneRefused(f"the {pulse.valve} pulse at {sent_s:.3f} s is open to the end of "
                          "the recording: the recording is incomplete")
    # the loop time from the tick that opened the valve to the one that shut it, not
    # the samples between: a tick a busy PC skipped (overrun_policy skip) leaves no
    # sample, but its time passed with the valve open (a 300 ms pulse showed 267 samples)
    shown = float(t_s[i1] - t_s[i0])
    if i1 - i0 != open_i.size or abs(shown - want) > 1.5 * dt:
        raise TuneRefused(f"the {pulse.valve} pulse sent at {sent_s:.3f} s was open "
                          f"{1e3 * shown:.0f} ms in the recording, not {1e3 * want:g} ms")
    settled = i1 + round(SETTLE_AFTER_S / dt)
    if i0 < n_w or settled + n_w > len(t_s):
        raise TuneRefused(f"the {pulse.valve} pulse at {sent_s:.3f} s lacks the recording "
                          "around it: the recording is incomplete")
    before, after = slice(i0 - n_w, i0), slice(settled, settled + n_w)
    p0, l0 = float(np.mean(p_bar[before])), float(np.mean(l_mm[before]))
    speed, k = fastest(l_mm[i0:settled], dt)
    shows = slice(max(0, i0 - 2 * n_w), min(len(t_s), settled + 2 * n_w))
    trace = PulseTrace(t_s[shows] - t_s[i0], p_bar[shows], l_mm[shows],
                       float(t_s[settled] - t_s[i0]), p0, l0, float(t_s[i0 + k] - t_s[i0]))
    return PulseResponse(pulse, shown, round((shown - want) / dt) * dt,
                         float(np.mean(p_bar[after])) - p0,
                         float(np.mean(l_mm[after])) - l0, speed,
                         trace), slice(i0 - n_w, settled + n_w)


def unsound(r: PulseResponse) -> str | None:
    """What the rules cannot use in one pulse's response (None: it is sound): a rate or
    shortest pulse that moved the pressure no way or the wrong way, a speed pulse that
    moved no length."""
    if r.pulse.pulse_s != SPEED_PULSE_S:
        sign = 1.0 if r.pulse.valve == "inflate" else -1.0
        if not sign * r.pressure_step_bar >= MIN_STEP_BAR:
            return (f"moved the pressure by {r.pressure_step_bar:+.4f} bar: it must "
                    f"{'raise' if sign > 0 else 'lower'} it by {MIN_STEP_BAR:g} bar or more")
        return None
    sign = -1.0 if r.pulse.valve == "inflate" else 1.0  # inflating contracts
    if not sign * r.length_step_mm >= MIN_LENGTH_MM:
        return (f"moved the length by {r.length_step_mm:+.3f} mm: it must "
                f"{'shorten' if sign < 0 else 'lengthen'} the muscle by {MIN_LENGTH_MM:g} mm "
                "or more")
    return None


def check(test: StepTest) -> None:
    """Refuse (TuneRefused, the reason and what to check) a test that did not measure
    what the rules need: a pulse that is `unsound`, a valve none of whose shortest
    pulses is `counted` (each ran longer than the PWM's shortest: the PC skipped a
    tick near the end of each), no length change at all."""
    for r in test.responses():
        why = unsound(r)
        if why is None:
            continue
        what = ("(a length sensor that does not follow, a muscle held by an end stop, or "
                "too little load to stretch it?)" if r.pulse.pulse_s == SPEED_PULSE_S else
                "(no supply, a valve that does not open, swapped inflate and exhaust "
                "channels, or the valve's on-delay longer than valve_on_delay_s says?)")
        raise TuneRefused(f"the {r.pulse.valve} valve's {1e3 * r.pulse_s:.0f} ms pulse "
                          f"{why} {what}")
    measured = measurements(test)
    for valve in ("inflate", "exhaust"):
        repeats = shortest_of(measured, valve)
        if not any(counted(repeats)):
            lengths = ", ".join(f"{1e3 * r.pulse_s:.0f}" for r in test.shortest
                                if r.pulse.valve == valve)
            raise TuneRefused(f"none of the {valve} valve's shortest pulses ran the PWM's "
                              f"shortest pulse (open {lengths} ms in the recording): the PC "
                              "skipped ticks (overruns); run it again on a quieter machine "
                              "or with loop.realtime")
    if not test.count_mm > 0.0:
        raise TuneRefused("the length never changed during the step test: is the length "
                          "sensor connected?")


def print_test(title: str, test: StepTest) -> None:
    print(title)
    print(f"  {'pulse':18s} {'open ms':>8s} {'pressure bar':>13s} {'length mm':>10s} "
          f"{'fastest mm/s':>13s}")
    for r in test.responses():
        print(f"  {r.pulse.valve:18s} {1e3 * r.pulse_s:8.0f} {r.pressure_step_bar:+13.4f} "
              f"{r.length_step_mm:+10.3f} {r.speed_mm_s:13.1f}")
    m = measurements(test)
    fill, vent = shortest_of(m, "inflate"), shortest_of(m, "exhaust")
    print(f"  shortest pulses' typical step: inflate {typical_step_bar(fill):+.4f}, exhaust "
          f"{typical_step_bar(vent):+.4f} bar (of {sum(counted(fill))} and "
          f"{sum(counted(vent))} of {SHORTEST_REPEATS})")
    print(f"  encoder count (the smallest length change): {test.count_mm:g} mm")


def print_settings(muscle: str, present: dict[str, float], new: dict[str, float]) -> None:
    """The derived settings beside the present ones, by config key."""
    print(f"Settings (muscles[{muscle}].onoff):")
    print(f"  {'key':28s} {'present':>10s} {'new':>10s} {'change':>8s}")
    for key, value in new.items():  # as --save writes them
        print(change_row(key, 28, present[key], value))

"""The feedforward's watch over its model (one muscle): inputs off the training domain
counted, said once and faded to the position PID alone; a feedforward that oscillates
against the pressure loop found and said.

Off the data (`control.feedforward.off_data`, `pamd.models.domain`): every tick the
feedforward's inputs and output are judged against the model's training domain
(`Feedforward.off_mask`, a table lookup). With ``fade`` the feedforward's weight moves
toward 0 while they are outside and back toward 1 once inside, at 1 / `fade_s` per
second, and what the weight takes from the feedforward goes into the position PID's
integral (and back), so the setpoint never jumps (bumpless both ways). ``warn`` counts
and says, ``off`` does not judge.

Oscillation (`OscillationWatch`): a quasi-static inverse model follows the target's
motion and the load, so its feedforward turns round where the target does (twice a
cycle of a sine, plus a bend at the hysteresis knee). Through its force input it also
sees the load's inertia: a pressure step accelerates the hanging mass, the force
swings at the load's bounce frequency (10-15 Hz for tens of kg on a DMSP-20), and the
model's pressure for that force swings back into the pressure loop. With the physical
force slope dP/dF = 1 / A(k), about 1/150 bar/N, that loop's gain is far below one
(the force low-pass divides it by 2 pi f tau, about 40 at 12 Hz with 0.5 s); a model
whose consequents blew up between its training loads has a slope tens of times
steeper, and the loop rings. The criterion: within `WINDOW_S` the feedforward turns
round by at least `REVERSAL_BAR` at least `EXTRA_REVERSALS` more times than the
target length turns round by `TARGET_REVERSAL_MM` (three periods of an oscillation the
motion does not ask for). Said once an episode as a `feedforward` event; the record's
flag FF_OSCILLATING marks its ticks.

All on the tick path (`OffData.tick`, called by `pamd.loop.control.length_control`): float
arithmetic on preallocated slots; the event's payload is built off the tick
(`pamd.loop.control.rig_report.feedforward_events`), from the floats kept here.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pamd.wire.tick import Flag

if TYPE_CHECKING:
    from pamd.loop.control.incremental_pid import IncrementalPid
    from pamd.loop.control.pid import Pid

F_OFF, F_FADED, F_OSC = int(Flag.FF_OFF_DATA), int(Flag.FF_FADED), int(Flag.FF_OSCILLATING)
#: Share of the running ticks' judged (percent) figures are rounded to.
PCT_DIGITS = 2
#: A reversal of the feedforward counts when it moves back by at least this much: four
#: times the pressure sensor's 5 mbar quantum, a tenth of the 0.5 bar tracking band.
REVERSAL_BAR = 0.02
#: A reversal of the target length counts when it moves back by at least this much.
TARGET_REVERSAL_MM = 0.05
#: The window reversals are counted over, s.
WINDOW_S = 1.0
#: Reversals of the feedforward beyond the target's within the window that make an
#: oscillation (three full periods).
EXTRA_REVERSALS = 6
#: How long without a turn that makes the excess before an oscillation has ended, s.
QUIET_S = 2.0


class _Reversals:
    """Counts the turns of one signal (moves back by at least `step`) and keeps the
    times of the last `keep` turns in a ring."""

    __slots__ = ("step", "ext", "direction", "times", "head", "count", "turn_ext", "swing")

    def __init__(self, step: float, keep: int) -> None:
        self.step = step
        self.ext = math.nan
        self.direction = 0
        self.turn_ext = math.nan  # the extreme the last turn left
        self.swing = 0.0  # the distance between the last two turns' extremes
        self.times = [-math.inf] * keep
        self.head = 0
        self.count = 0

    def reset(self) -> None:
        self.ext = self.turn_ext = math.nan
        self.swing = 0.0
        self.direction = 0
        for i in range(len(self.times)):
            self.times[i] = -math.inf
        self.count = 0

    def update(self, now: float, x: float) -> None:
        e = self.ext
        d = self.direction
        if d == 0:  # no way yet: from the first value, the first move of a step
            if e != e:
                self.ext = x
            elif x - e >= self.step or e - x >= self.step:
                self.direction = 1 if x > e else -1
                self.ext = x
            return
        if (x - e) * d > 0.0:
            self.ext = x  # further the same way
        elif (e - x) * d >= self.step:  # turned round
            self.direction = -d
            self.ext = x
            t = self.turn_ext
            self.swing = abs(e - t) if t == t else 0.0
            self.turn_ext = e
            times = self.times
            times[self.head] = now
            self.head = (self.head + 1) % len(times)
            self.count += 1

    def within(self, now: float, window_s: float) -> int:
        since = now - window_s
        n = 0
        for t in self.times:
            if t >= since:
                n += 1
        return n


class OscillationWatch:
    """The oscillation criterion of the module doc, on the feedforward and its target.
    The window is counted only on the ticks the feedforward turns round."""

    __slots__ = ("ff", "target", "active", "episodes", "last_s", "amplitude_bar", "fresh")

    def __init__(self) -> None:
        keep = 4 * EXTRA_REVERSALS
        self.ff = _Reversals(REVERSAL_BAR, keep)
        self.target = _Reversals(TARGET_REVERSAL_MM, keep)
        self.active = False
        self.episodes = 0
        self.last_s = -math.inf  # the last turn that made the excess
        self.amplitude_bar = 0.0  # half the feedforward's widest swing in the episode
        self.fresh = False  # an episode began (the muscle says it once)

    def reset(self) -> None:
        self.ff.reset()
        self.target.reset()
        self.active = False
        self.last_s = -math.inf
        self.amplitude_bar = 0.0

    def step(self, now: float, ff_bar: float, target_mm: float) -> bool:
        """True while the feedforward oscillates against the pressure loop."""
        turns = self.ff.count
        self.ff.update(now, ff_bar)
        self.target.update(now, target_mm)
        if self.ff.count != turns and (self.ff.within(now, WINDOW_S)
                                       - self.target.within(now, WINDOW_S)
                                       >= EXTRA_REVERSALS):
            self.last_s = now
            if not self.active:
                self.active = True
                self.episodes += 1
                self.fresh = True
                self.amplitude_bar = 0.0
            half = 0.5 * self.ff.swing
            if half > self.amplitude_bar:
                self.amplitude_bar = half
        if self.active and now - self.last_s >= QUIET_S:
            self.active = False
        return self.active


class OffData:
    """One muscle's watch over its feedforward (see the module doc): the weight of the
    feedforward, the counts of the running ticks judged, off the domain and faded, and
    what to say once."""

    __slots__ = ("policy", "fade_s", "weight", "ticks", "off_ticks", "faded_ticks",
                 "osc_ticks", "said", "pending_off", "pending_osc", "mask", "values",
                 "oscillation")

    def __init__(self, policy: str, fade_s: float) -> None:
        self.policy = policy
        self.fade_s = fade_s
        self.weight = 1.0
        self.ticks = self.off_ticks = self.faded_ticks = self.osc_ticks = 0
        self.said = False  # off the data said since the model or the mode came
        self.pending_off = False  # off the data: an event to say
        self.pending_osc = False  # an oscillation: an event to say
        self.mask = 0  # the first off-domain tick's mask
        self.values = [math.nan] * 5  # its force, length, contraction, velocity, output
        self.oscillation = OscillationWatch()

    @property
    def judging(self) -> bool:
        return self.policy != "off"

    def restart(self) -> None:
        """A mode entered or a model swapped: full weight, say again when off."""
        self.weight = 1.0
        self.said = False
        self.oscillation.reset()

    def tick(self, now: float, dt: float, mask: int, counted: bool, ff: float,
             f: float, ln: float, x: float, v: float, target_mm: float,
             pid: Pid | None, inc: IncrementalPid | None) -> int:
        """This tick's judgement of the feedforward `ff` (the model's output for force
        `f`, length `ln`, contraction `x` and velocity `v`; `mask` its domain test):
        counted, faded and watched. With a position PID (position mode: `pid` given),
        what the weight takes from the feedforward goes into the PID's integral (or
        Method 2's sum), and back as it returns, so the setpoint does not jump. Returns
        the record's flags; `weight` is the feedforward's weight from now."""
        before = self.weight
        if mask and not self.said:
            self.keep(f, ln, x, v, ff)
        w = self.step(mask, dt, counted, pid is not None)
        if w != before and pid is not None:
            moved = (before - w) * ff  # the feedforward's part that changes hands
            il = pid.integral_limit
            i = pid.i + moved
            pid.i = il if i > il else (-il if i < -il else i)
            if inc is not None and inc.method == 2:  # Method 1 keeps no sum to move into
                u, lim = inc.u + moved, inc.limit
                inc.u = lim if u > lim else (-lim if u < -lim else u)
        flags = F_OFF if mask else 0
        if w < 1.0:
            flags |= F_FADED
        if self.watch(now, ff, target_mm, counted):
            flags |= F_OSC
        return flags

    def step(self, mask: int, dt: float, counted: bool, fades: bool) -> float:
        """This tick's feedforward weight after judging `mask` (0: inside). `counted`:
        a running tick (the shares' denominator); `fades`: the weight may leave 1
        (`fade`, in position mode)."""
        w = self.weight
        if fades and self.policy == "fade":
            if mask:
                w = w - dt / self.fade_s if w > dt / self.fade_s else 0.0
            elif w < 1.0:
                w = w + dt / self.fade_s if w < 1.0 - dt / self.fade_s else 1.0
        elif w != 1.0:
            w = 1.0
        self.weight = w
        if counted:
            self.ticks += 1
            if mask:
                self.off_ticks += 1
            if w < 1.0:
                self.faded_ticks += 1
        if mask and not self.said and self.policy != "off":
            self.said = True
            self.mask = mask
            self.pending_off = True
        return w

    def keep(self, force_n: float, length_mm: float, contraction: float,
             velocity_mm_s: float, output_bar: float) -> None:
        """The values of the tick that went off the domain (for the event)."""
        v = self.values
        v[0], v[1], v[2], v[3], v[4] = force_n, length_mm, contraction, velocity_mm_s, \
            output_bar

    def watch(self, now: float, ff_bar: float, target_mm: float, counted: bool) -> bool:
        """The oscillation watch on this tick's feedforward; True while it oscillates."""
        osc = self.oscillation
        on = osc.step(now, ff_bar, target_mm)
        if counted and on:
            self.osc_ticks += 1
        if osc.fresh:
            osc.fresh = False
            self.pending_osc = True
        return on

    def summary(self) -> dict[str, float | int | str | None]:
        """What the run summary and the status say of it (percent of the running ticks
        with the feedforward in use; None: none ran)."""
        n = self.ticks

        def pct(k: int, judged: bool = True) -> float | None:
            return round(100.0 * k / n, PCT_DIGITS) if n and judged else None

        judged = self.policy != "off"
        return {"off_data": self.policy, "off_data_pct": pct(self.off_ticks, judged),
                "faded_pct": pct(self.faded_ticks, judged),
                "oscillating_pct": pct(self.osc_ticks),
                "oscillations": self.oscillation.episodes, "ticks": n}

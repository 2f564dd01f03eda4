"""Online adaptation of a muscle's inverse model: its rule consequents follow the muscle
as it drifts (it warms, its braid wears), by recursive least squares with forgetting
(`pamd.models.anfis.rls`) on what the rig measures while a length mode runs.

The stage (`Adaptation`, owned by the muscle; seed 001 names the time-varying
behaviour this corrects):

* **Sample.** Every tick of a length mode with the model in use, the measured force,
  length, contraction and pressure are summed, and the measured length runs through
  the model's own velocity filter (the signal its velocity input was trained on).
  Every `update_period_s` the means are one sample: the model is evaluated at the
  mean inputs (its regressor phi, `CompiledAnfis.regressor`) and the mean measured
  pressure is its target. The inverse model maps what the muscle does to the pressure
  that does it, so the measured pressure (not the command) is the truth.
  With `control.position.model_sweep_hz` the velocity input is on the feedforward's
  time scale (`LengthControl.vel_scale`: the filter's window and the velocity times
  it), so the rules adapted are the rules the feedforward reads.
* **Gated.** A window is dropped (state PAUSED) if any of its ticks was outside
  RUNNING or LOAD_CHANGE, in a safe state, had a flag that says the *measurement* is
  not the muscle's (`BAD_FLAGS`: stale, no length datum, exhaust open, pressure not
  following its command; on on/off valves the exhaust's PWM pulses are the control
  itself, as the inflate valve's are, and do not: `ONOFF_BAD_FLAGS`), had an
  untrusted signal, or if the sample's own inputs fall outside the model's training
  ranges. Flags that say the *command* was limited (pressure or contraction limit,
  slew limit, PID saturated, feedforward clipped) do not: the muscle's measured state
  and pressure are still a true sample of its inverse, and they come exactly where a
  weakening muscle needs the model most (at the top of the stroke, near the pressure
  limit).
* **Bounded**, in bar of output over the training ranges (`OutputBound`, on a grid):
  a step longer than `max_rate_bar_per_s` x the update period is shortened to it
  (the rate bound holds for every second); an update that would take the model
  further than `max_total_bar` from the trained one, or that is not finite, is
  refused: the parameters stay as they were, adaptation freezes (state FROZEN) and
  the reason is reported (`take_report`, an `adapt` event). Never a fault: the rig
  goes on with the last good model. The covariance trace never passes its start
  (wind-up), and `reset()` puts it back there.
* **Recorded**: `drift_bar` (the adapted minus the trained model's output at the
  last sample's inputs) and `state` go into the tick record (`adapt_drift_bar`,
  `adapt_state`).

Everything on the tick path is float arithmetic on attributes, and the update (one
in 20 ticks by default) numpy calls on buffers allocated by `bind`.
"""

from __future__ import annotations

import math
import time
from enum import IntEnum
from typing import TYPE_CHECKING, cast

import numpy as np

from pamd.models.anfis.compiled import CompiledAnfis
from pamd.models.anfis.rls import OutputBound, Rls
from pamd.models.velocity import VelocityFilter
from pamd.wire.declare.fields import PWM_VALVE_FLAGS
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import Flag, MuscleTick, State

if TYPE_CHECKING:
    from pamd.config.schema import AdaptConfig
    from pamd.loop.control.feedforward import Feedforward
    from pamd.loop.control.inputs import Inputs
    from pamd.loop.control.length_control import LengthControl
    from pamd.models.anfis.model import AnfisModel

S_RUNNING, S_LOAD = int(State.RUNNING), int(State.LOAD_CHANGE)
#: Flags that say a tick's measurement is not the muscle's own (module docstring).
BAD_FLAGS = int(Flag.STALE | Flag.NO_LENGTH_DATUM | Flag.EXHAUST_OPEN | Flag.TRACKING)
#: On on/off valves the exhaust's PWM pulses are the control itself (`PWM_VALVE_FLAGS`).
ONOFF_BAD_FLAGS = BAD_FLAGS & ~int(PWM_VALVE_FLAGS)
#: What the `adapt` command can do.
ACTIONS = ("on", "off", "reset", "restore", "status")
#: Shortest time between two reports of the rate bound (the rest are counted).
RATE_REPORT_EVERY_S = 60.0


class AdaptState(IntEnum):
    """`adapt_state` in the tick record."""

    OFF = 0  # not switched on (or no model that can adapt)
    ADAPTING = 1  # the last window was taken
    PAUSED = 2  # the last window was dropped (not running, or a bad sample)
    FROZEN = 3  # an update was refused; the model stays until `adapt on` again
    LIMITED = 4  # the last step was shortened to the rate bound


class Adaptation:
    """One muscle's online adaptation (see the module docstring)."""

    def __init__(self, muscle: str, cfg: AdaptConfig, ff: Feedforward | None, *,
                 onoff: bool = False, inputs: Inputs | None = None,
                 length_control: LengthControl | None = None) -> None:
        """`inputs` and `length_control`: the muscle's, which `update` reads (a test that
        calls `step` itself needs neither)."""
        self.muscle = muscle
        self._inputs = inputs
        self._lc = length_control
        self.cfg = cfg
        self.bad_flags = ONOFF_BAD_FLAGS if onoff else BAD_FLAGS  # on/off: PWM_VALVE_FLAGS
        self.enabled = False
        self.state = int(AdaptState.OFF)
        self.drift_bar = 0.0
        self.total_bar = 0.0  # OutputBound of (theta - theta0)
        self.report: JsonObject | None = None
        self.why_not: str | None = "no model"
        self.ff: Feedforward | None = None
        self.compiled: CompiledAnfis | None = None
        self.rls: Rls | None = None
        self.bound: OutputBound | None = None
        self.theta0 = np.zeros(0)
        self.vel = VelocityFilter()
        self.vel_scale = 1.0  # the feedforward's velocity time scale (`step`)
        self.adapted_s = 0.0  # time of the windows taken
        self.started_unix: float | None = None
        self.refused = 0
        self.limited = 0
        self._last_rate_report = -math.inf
        self._t = 0.0  # adaptation's own clock (sum of dt while enabled)
        self._active = False  # the last tick was in use (running, in a length mode)
        self._uses_velocity = False
        self._reset_window()
        self.bind(ff)
        if cfg.enabled and self.why_not is None:
            self.switch(True)

    # -- set-up and commands (loop thread, between ticks) -----------------------------------
    def bind(self, ff: Feedforward | None) -> None:
        """A (new) model: its trained consequents are the baseline of the bounds and
        of the drift; any adaptation of the previous model ends with it."""
        self.ff, self.compiled, self.rls, self.bound = ff, None, None, None
        self.drift_bar = self.total_bar = 0.0
        self.adapted_s, self.refused, self.limited = 0.0, 0, 0
        self.started_unix = None
        if ff is None:
            self.why_not = "no model"
        elif not isinstance(ff.compiled, CompiledAnfis):
            self.why_not = (f"adaptation updates the rule consequents of an ANFIS or "
                            f"TS-fuzzy model; a {ff.model.kind} model has none")
        else:
            c = ff.compiled
            # an ANFIS or TS-fuzzy model (its compiled form checked above): the rule grid
            m = cast("AnfisModel", ff.model)
            self.compiled = c
            self.theta0 = c.theta(np.empty(c.n_consequents))
            self.bound = OutputBound.for_model(m)
            cfg = self.cfg
            lam = math.exp(-cfg.update_period_s / cfg.memory_s)
            self.rls = Rls(self.theta0, cfg.initial_variance_bar2, lam)
            self.vel.window_s = ff.velocity_window_s * self.vel_scale
            self._uses_velocity = "velocity_mm_s" in c.input_names
            self.why_not = None
        if self.why_not is not None:
            self.enabled = False
        elif self.enabled:  # adapting goes on, now on this model
            self.started_unix = time.time()
        self.state = int(AdaptState.ADAPTING if self.enabled else AdaptState.OFF)
        self._reset_window()

    def switch(self, on: bool) -> None:
        """On (also out of FROZEN: the operator's decision) or off; the parameters stay.
        ValueError (the reason) if the model cannot adapt."""
        if on and self.why_not is not None:
            raise ValueError(self.why_not)
        if on and self.started_unix is None:
            self.started_unix = time.time()
        self.enabled = on
        self.state = int(AdaptState.PAUSED if on else AdaptState.OFF)
        self._reset_window()

    def reset(self) -> None:
        """The covariance back to its start (the parameters stay)."""
        if self.rls is not None:
            self.rls.reset()

    def restore(self) -> None:
        """The trained model's consequents back (covariance reset too)."""
        if self.rls is None or self.compiled is None:
            return
        self.rls.set_theta(self.theta0)
        self.rls.reset()
        self.compiled.set_consequents(self.theta0)
        if self.bound is not None:
            self.bound.clear()
        self.drift_bar = self.total_bar = 0.0

    def command(self, action: str) -> JsonObject:
        """The `adapt` command's action (ValueError with the reason if refused)."""
        if action == "on":
            self.switch(True)
        elif action == "off":
            self.switch(False)
        elif action == "reset":
            if self.rls is None:
                raise ValueError(self.why_not or "no model")
            self.reset()
        elif action == "restore":
            if self.rls is None:
                raise ValueError(self.why_not or "no model")
            self.restore()
        elif action != "status":
            raise ValueError(f"unknown action {action!r}; use {', '.join(ACTIONS)}")
        return self.describe()

    def take_report(self) -> JsonObject | None:
        r, self.report = self.report, None
        return r

    def describe(self) -> JsonObject:
        """What a verdict, a status or a saved model's provenance says of it."""
        cfg = self.cfg
        return {"muscle": self.muscle, "enabled": self.enabled,
                "state": AdaptState(self.state).name.lower(),
                "drift_bar": self.drift_bar, "total_bar": self.total_bar,
                "updates": 0 if self.rls is None else self.rls.updates,
                "adapted_s": self.adapted_s, "refused": self.refused,
                "rate_limited": self.limited,
                "covariance_trace": None if self.rls is None else self.rls.trace,
                "bounds": {"max_rate_bar_per_s": cfg.max_rate_bar_per_s,
                           "max_total_bar": cfg.max_total_bar, "memory_s": cfg.memory_s,
                           "update_period_s": cfg.update_period_s,
                           "initial_variance_bar2": cfg.initial_variance_bar2},
                **({"why_not": self.why_not} if self.why_not else {})}

    def snapshot(self) -> JsonObject:
        """A copy of the present consequents (column by column, `CompiledAnfis.theta`)
        with what a saved model's provenance needs (`pamd.models.anfis.adapted`);
        ValueError if there is no model that adapts."""
        if self.rls is None or self.ff is None:
            raise ValueError(self.why_not or "no model")
        return {"muscle": self.muscle, "source": self.ff.source, "sha256": self.ff.sha256,
                "consequents": self.rls.theta.tolist(),
                "started_unix": self.started_unix, **self.describe()}

    # -- the tick ---------------------------------------------------------------------------
    def _reset_window(self) -> None:
        """Start over: an empty window, the velocity filter from rest; windows stay bad
        until the filter has settled (3 of its time constants)."""
        self._n = 0
        self._sf = self._sl = self._sx = self._sp = 0.0
        self._win = 0.0
        self._bad = False
        self.vel.reset()
        self._warm_s = 3.0 * self.vel.window_s if self._uses_velocity else 0.0

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        """The muscle's write, last (enabled only): `step` with the model in use where a
        length mode runs with it and the tick is not held to a safe state."""
        lc, inp = self._lc, self._inputs
        assert lc is not None and inp is not None  # the muscle's (`__init__`)
        self.step(dt, t.state, t.flags, inp, lc.active and lc.use_ff and not t.held,
                  lc.vel_scale)

    def step(self, dt: float, state: int, flags: int, inp: Inputs, in_use: bool,
             vel_scale: float = 1.0) -> None:
        """One tick (enabled only): sum the sample, gate it, update at the window's end.
        `in_use`: a length mode runs with the model, outside the safe states;
        `vel_scale`: the feedforward's velocity time scale (`LengthControl.vel_scale`)."""
        self._t += dt
        if vel_scale != self.vel_scale:  # a new profile's time scale: start over on it
            self.vel.window_s *= vel_scale / self.vel_scale
            self.vel_scale = vel_scale
            self._reset_window()
        if self.state == AdaptState.FROZEN:
            return
        if not in_use or not (state == S_RUNNING or state == S_LOAD):
            if self._active:  # starts over when it runs again
                self._active = False
                self._reset_window()
            self.state = int(AdaptState.PAUSED)
            return
        self._active = True
        ln = inp.length_mm
        self.vel.update(ln, dt)
        if self._warm_s > 0.0:
            self._warm_s -= dt
            self._bad = True
        if flags & self.bad_flags or not (inp.pressure_ok and inp.length_ok
                                     and inp.plausibility.force_ok):
            self._bad = True
        self._sf += inp.force_n
        self._sl += ln
        self._sx += inp.contraction
        self._sp += inp.pressure_bar
        self._n += 1
        self._win += dt
        if self._win < self.cfg.update_period_s:
            return
        n, bad, win = self._n, self._bad, self._win
        self._n, self._bad, self._win = 0, False, 0.0
        f, ln, x, p = self._sf / n, self._sl / n, self._sx / n, self._sp / n
        self._sf = self._sl = self._sx = self._sp = 0.0
        if bad:
            self.state = int(AdaptState.PAUSED)
            return
        self._update(f, ln, x, self.vel.value * self.vel_scale, p, win)

    def _update(self, f: float, ln: float, x: float, v: float, p: float, win: float) -> None:
        ff, c, rls, bound = self.ff, self.compiled, self.rls, self.bound
        assert ff is not None and c is not None and rls is not None and bound is not None
        ff.pressure(f, ln, x, v)
        if ff.clipped:  # outside the training ranges: nothing to learn there
            self.state = int(AdaptState.PAUSED)
            return
        phi = c.regressor()
        cand = rls.propose(phi, p)
        if cand is None:
            self._refuse("the update is not finite (sample or covariance)", p)
            return
        cfg = self.cfg
        limit = cfg.max_rate_bar_per_s * win
        size = bound.propose(rls.step)
        state = AdaptState.ADAPTING
        if size > limit:
            rls.scale_step(limit / size)
            bound.scale_step(limit / size)
            state = AdaptState.LIMITED
            self.limited += 1
        # the total bound, on the candidate against the trained consequents
        total = bound.total_with_step()
        if not total <= cfg.max_total_bar:
            self._refuse(f"the model would move {total:.3f} bar from the trained one, past "
                         f"adapt.max_total_bar {cfg.max_total_bar:g} bar", p)
            return
        rls.commit()
        bound.commit()
        c.set_consequents(rls.theta)
        self.total_bar = total
        np.subtract(rls.theta, self.theta0, out=rls.step)  # step's buffer is free now
        self.drift_bar = float(np.dot(phi, rls.step))
        self.adapted_s += win
        self.state = int(state)
        if state == AdaptState.LIMITED and self._t - self._last_rate_report >= \
                RATE_REPORT_EVERY_S:
            self._last_rate_report = self._t
            self.report = {"muscle": self.muscle, "action": "rate_bound",
                           "reason": f"{self.muscle}: adaptation step shortened to "
                                     f"adapt.max_rate_bar_per_s {cfg.max_rate_bar_per_s:g} "
                                     f"bar/s ({self.limited} times so far)",
                           "drift_bar": self.drift_bar, "total_bar": total}

    def _refuse(self, why: str, p: float) -> None:
        """Keep the parameters, freeze, say why (the controller makes it an event)."""
        self.refused += 1
        self.state = int(AdaptState.FROZEN)
        self.report = {"muscle": self.muscle, "action": "frozen",
                       "reason": f"{self.muscle}: adaptation frozen: {why}; the model "
                                 "keeps its last parameters (`adapt on` resumes, `adapt "
                                 "restore` goes back to the trained model)",
                       "pressure_bar": p, "drift_bar": self.drift_bar,
                       "total_bar": self.total_bar}

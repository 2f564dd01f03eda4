"""The length modes of a muscle: the ANFIS inverse model as feedforward, an outer
position loop, and iterative learning across cycles.

Modes (`pamd.tick.Mode`), per muscle:

* ``pressure``: the pressure setpoint comes from a pressure profile or setpoint
  (`pamd.control.muscle`); nothing here runs.
* ``length_force``: targets for length and force go through the model to the
  pressure setpoint, which the PID pressure loop follows. No length feedback: the
  model is the controller (seed 000's use of the inverse model).
* ``position``: a length target; the model takes the *measured* force and the target
  length (and the target's velocity) and gives the pressure it needs; an outer PID on
  the length error adds what the model misses; optionally an iterative learning
  correction (ILC) learned over repeated cycles of a periodic length profile
  (seed 003's PID-type ILC: u_{j+1}(t) = u_j(t) + Kp e_j(t + lead) + Kd de_j/dt). With
  ``feedforward: false`` the outer PID (+ ILC) runs alone, without a model.

Inputs outside the model's training ranges are clipped to them, never extrapolated,
and the tick sets `Flag.FF_CLIPPED`. A model's velocity input is the target length
run through the filter its training data went through (`pamd.control.velocity`,
with the window stated in the model file), so it is the signal the model learned.

Everything on the tick path (`LengthControl.step`, `Feedforward.pressure`,
`Ilc.step`) is plain float arithmetic on attributes prepared outside the loop; model
files are read and compiled outside the loop's thread (config load, or the daemon
before it queues a `model` command) and the loop only swaps the compiled object.
"""

from __future__ import annotations

import hashlib
import math
import os
from array import array
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from pamd.anfis.model import AnfisModel
from pamd.anfis.modelfile import load
from pamd.control.pid import Pid
from pamd.control.profiles import Profile, ProfileSpec
from pamd.control.velocity import MODEL_VELOCITY_WINDOW_S, VelocityFilter
from pamd.errors import CommandRefused, ModelError
from pamd.muscle import equilibrium_contraction
from pamd.tick import Flag, Mode, State

if TYPE_CHECKING:
    from pamd.config.loader import MuscleLimitsResolved
    from pamd.config.schema import MuscleConfig, PositionConfig

#: Signals a model input can be fed from, in the order `Feedforward.pressure` takes them.
SOURCES: tuple[str, ...] = ("force_n", "length_mm", "contraction", "velocity_mm_s")
LENGTH_INPUTS: tuple[str, ...] = ("length_mm", "contraction")
MODEL_OUTPUT = "pressure_bar"
#: Largest rule count accepted for the tick (about 25 us single-sample at 1 kHz; the
#: seeds' layouts are 25 and 27 rules).
MAX_RULES = 125

#: Length targets keep this far (contraction) inside what the load lets the muscle reach.
REACH_MARGIN = 0.005

#: Time constant of the setpoint's rate estimate (for the rate feedforward), s.
SP_RATE_WINDOW_S = 0.05

F_CLIP, F_SLEW = int(Flag.FF_CLIPPED), int(Flag.SLEW_LIMITED)
S_RUNNING, S_LOAD = int(State.RUNNING), int(State.LOAD_CHANGE)
MODE_NAMES: dict[str, Mode] = {"pressure": Mode.PRESSURE, "length_force": Mode.LENGTH_FORCE,
                               "position": Mode.POSITION}


# -- model checks (outside the loop) ------------------------------------------------------
def model_problems(model: AnfisModel, nominal_length_mm: float, max_contraction: float,
                   max_pretension: float) -> list[str]:
    """Why `model` cannot drive this muscle (empty list: it can)."""
    out = []
    names = [v.name for v in model.inputs]
    if model.output.name != MODEL_OUTPUT:
        out.append(f"its output is {model.output.name!r}, not {MODEL_OUTPUT!r}")
    unknown = [n for n in names if n not in SOURCES]
    if unknown:
        out.append(f"input(s) {', '.join(unknown)} are not signals of the tick (known: "
                   f"{', '.join(SOURCES)})")
    if "force_n" not in names:
        out.append("it has no force_n input")
    lengths = [n for n in names if n in LENGTH_INPUTS]
    if len(lengths) != 1:
        out.append("it needs exactly one of the inputs length_mm or contraction")
    if "velocity_mm_s" in names and velocity_window(model) is None:
        out.append("its velocity_mm_s input does not state its filter (derived_inputs."
                   "velocity_mm_s.window_s, a time constant > 0 s), so the tick cannot "
                   "compute the signal it was trained on")
    if model.n_rules > MAX_RULES:
        out.append(f"{model.n_rules} rules is too many for the tick (at most {MAX_RULES}); "
                   "use fewer membership functions (e.g. 3 on the velocity)")
    lo_mm = nominal_length_mm * (1.0 - max_contraction)
    hi_mm = nominal_length_mm * (1.0 + max_pretension)
    for v in model.inputs:
        if v.name == "length_mm" and (v.max < lo_mm or v.min > hi_mm):
            out.append(f"it was trained on lengths {v.min:.1f}-{v.max:.1f} mm but this muscle "
                       f"moves within {lo_mm:.1f}-{hi_mm:.1f} mm (nominal "
                       f"{nominal_length_mm:g} mm)")
        if v.name == "contraction" and (v.max < -max_pretension or v.min > max_contraction):
            out.append(f"it was trained on contractions {v.min:.3f}-{v.max:.3f} but this "
                       f"muscle moves within {-max_pretension:.3f}-{max_contraction:.3f}")
    return out


def velocity_window(model: AnfisModel) -> float | None:
    """The time constant of the model's velocity input filter (None if not stated)."""
    w = (model.derived_inputs.get("velocity_mm_s") or {}).get("window_s")
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not 0 < w < math.inf:
        return None
    return float(w)


def load_model_for(path: str, muscle: MuscleConfig, limits: MuscleLimitsResolved) -> AnfisModel:
    """Load a model file and check it against a muscle; `ModelError` says why not."""
    model = load(path)
    problems = model_problems(model, muscle.nominal_length_mm, limits.max_contraction,
                              limits.max_pretension)
    if problems:
        raise ModelError(f"model file {path} cannot drive muscle {muscle.name!r}: "
                         + "; ".join(problems))
    return model


class LoadedModel:
    """A model file read and checked for one muscle (kept in `LoadedConfig.models`);
    each controller compiles its own `Feedforward` from it."""

    __slots__ = ("model", "path", "sha256")

    def __init__(self, model: AnfisModel, path: str, sha256: str) -> None:
        self.model, self.path, self.sha256 = model, path, sha256

    @classmethod
    def read(cls, path: str, muscle: MuscleConfig, limits: MuscleLimitsResolved) -> LoadedModel:
        model = load_model_for(path, muscle, limits)
        with open(path, "rb") as fh:
            digest = hashlib.sha256(fh.read()).hexdigest()
        return cls(model, os.path.abspath(path), digest)

    def feedforward(self) -> Feedforward:
        return Feedforward(self.model, self.path, self.sha256)


# -- the compiled model --------------------------------------------------------------------
class Feedforward:
    """A compiled model with its inputs wired to the tick's signals.

    `pressure(force_n, length_mm, contraction, velocity_mm_s)` evaluates the model on
    the inputs it has (in its own input order), holds the result to the output's
    training range and sets `clipped` if an input or the output had to be held."""

    __slots__ = ("model", "source", "sha256", "compiled", "clipped", "velocity_window_s",
                 "out_lo", "out_hi", "_call")

    def __init__(self, model: AnfisModel, source: str = "", sha256: str = "") -> None:
        self.model = model
        self.source = source
        self.sha256 = sha256
        compiled = model.compile()
        self.compiled = compiled
        self.clipped = False
        self.velocity_window_s = velocity_window(model) or MODEL_VELOCITY_WINDOW_S
        self.out_lo, self.out_hi = model.output.min, model.output.max
        self._call = _wire(compiled.evaluate, [SOURCES.index(v.name) for v in model.inputs])

    @classmethod
    def from_file(cls, path: str, muscle: MuscleConfig,
                  limits: MuscleLimitsResolved) -> Feedforward:
        return LoadedModel.read(path, muscle, limits).feedforward()

    def pressure(self, force_n: float, length_mm: float, contraction: float,
                 velocity_mm_s: float) -> float:
        y = self._call(force_n, length_mm, contraction, velocity_mm_s)
        clipped = self.compiled.clipped
        # Inside the inputs' ranges but off the data (a load and length never seen
        # together) a model can still answer nonsense: its output is held to the range
        # it was trained on, and that counts as clipped too.
        if y > self.out_hi:
            y, clipped = self.out_hi, True
        elif y < self.out_lo:
            y, clipped = self.out_lo, True
        self.clipped = clipped
        return y

    def describe(self) -> dict[str, Any]:
        m = self.model
        return {"file": self.source, "sha256": self.sha256,
                "inputs": [v.name for v in m.inputs], "rules": m.n_rules,
                "ranges": {v.name: [v.min, v.max] for v in m.inputs}}


def _wire(ev: Callable[..., float], idx: list[int]) -> Callable[[float, float, float, float],
                                                                float]:
    """A call taking all four tick signals and passing the model its own inputs."""
    if len(idx) == 2:
        i, j = idx

        def call2(f: float, ln: float, x: float, v: float) -> float:
            a = (f, ln, x, v)
            return ev(a[i], a[j])

        return call2
    if len(idx) == 3:
        i, j, k = idx

        def call3(f: float, ln: float, x: float, v: float) -> float:
            a = (f, ln, x, v)
            return ev(a[i], a[j], a[k])

        return call3

    def call(f: float, ln: float, x: float, v: float) -> float:
        a = (f, ln, x, v)
        return ev(*[a[n] for n in idx])

    return call


# -- iterative learning --------------------------------------------------------------------
class Ilc:
    """A correction over one cycle of a periodic length profile, learned across cycles.

    The cycle is cut into bins of about `resolution_s`. Each tick applies the present
    bin's correction and, for the next cycle, moves the bin `lead_s` earlier by
    gain x error (+ gain_d x error rate), pro rata of the tick's share of a bin; the
    error is first low-passed over a bin. Each bin, once learned for the cycle, is
    smoothed with its neighbours (1/4, 1/2, 1/4: the Q-filter that keeps noise and
    fast dynamics from piling up cycle after cycle) and shrunk by `forgetting` per
    cycle; corrections are clamped to +-`limit_bar`. Error = measured - target
    length (mm): too long means more pressure."""

    __slots__ = ("period_s", "n", "bin_s", "lead", "gain", "gain_d", "keep", "limit", "u",
                 "e_f", "prev_e", "cycles", "last_cycle", "last_bin", "value")

    def __init__(self, period_s: float, gain_bar_per_mm: float, gain_d_bar_s_per_mm: float,
                 lead_s: float, forgetting: float, limit_bar: float, resolution_s: float) -> None:
        self.period_s = period_s
        self.n = max(3, round(period_s / resolution_s))
        self.bin_s = period_s / self.n
        self.lead = round(lead_s / self.bin_s)
        self.gain, self.gain_d = gain_bar_per_mm, gain_d_bar_s_per_mm
        self.keep = forgetting  # applied as (1 - forgetting * dt / period) per tick
        self.limit = limit_bar
        self.u = array("d", bytes(8 * self.n))
        self.e_f = math.nan
        self.prev_e = math.nan
        self.cycles = 0
        self.last_cycle = -1
        self.last_bin = -1
        self.value = 0.0

    def step(self, tau_s: float, error_mm: float, dt_s: float) -> float:
        """Correction at time `tau_s` into the periodic part of the profile."""
        cyc = int(tau_s / self.period_s)
        if cyc != self.last_cycle:
            self.last_cycle = cyc
            self.cycles += 1
        n = self.n
        k = int((tau_s - cyc * self.period_s) / self.bin_s)
        if k >= n:
            k = n - 1
        u = self.u
        lead = self.lead
        lim = self.limit
        if k != self.last_bin:
            if self.last_bin >= 0:  # the bin learned last is done for this cycle: smooth it
                j = (self.last_bin - lead) % n
                w = 0.25 * u[j - 1] + 0.5 * u[j] + 0.25 * u[(j + 1) % n]
                u[j] = lim if w > lim else (-lim if w < -lim else w)
            self.last_bin = k
        self.value = u[k]
        ef = self.e_f
        if ef != ef:
            ef = error_mm
        ef += dt_s / (self.bin_s + dt_s) * (error_mm - ef)
        pe = self.prev_e
        de = (ef - pe) / dt_s if pe == pe else 0.0
        self.e_f = self.prev_e = ef
        j = k - lead
        if j < 0:
            j += n
        w = u[j] * (1.0 - self.keep * dt_s / self.period_s) + dt_s / self.bin_s * (
            self.gain * ef + self.gain_d * de)
        u[j] = lim if w > lim else (-lim if w < -lim else w)
        return self.value


# -- the mode controller -------------------------------------------------------------------
class LengthControl:
    """What the length modes add to one muscle's tick (see the module docstring).

    Owned by a `MuscleController` (`muscle.length_ctl`); `enter`/`leave`/`swap` run
    in command handlers (the loop's thread, between ticks), `step` in the tick."""

    def __init__(self, muscle: Any, position: PositionConfig,
                 feedforward: Feedforward | None) -> None:
        self.m = muscle
        self.cfg = position
        pc = position.pid
        self.pid = Pid(pc.kp_bar_per_mm, pc.ki_bar_per_mm_s, pc.kd_bar_s_per_mm,
                       pc.derivative_filter_hz, pc.integral_limit_bar, pc.output_limit_bar)
        self.ff = feedforward
        self.use_ff = True
        self.position = False
        self.ilc: Ilc | None = None
        self.ilc_on = False
        # The target's velocity, filtered as the model's velocity input was in training.
        self.target_vel = VelocityFilter(MODEL_VELOCITY_WINDOW_S if feedforward is None
                                         else feedforward.velocity_window_s)
        self.sp_rate = VelocityFilter(SP_RATE_WINDOW_S)  # d(setpoint)/dt, bar/s
        # position mode: the measured force through a low-pass before the model. The
        # model is a quasi-static inverse; the force's fast part (damping, inertia,
        # noise) would close a loop pressure -> motion -> force -> model -> pressure.
        self.force_tau_s = position.force_filter_s
        self.force_lp = math.nan
        self.bump = 0.0
        self.bump_tau_s = position.bumpless_s
        self.flags = 0
        self.last_sp = math.nan
        self.correction = 0.0  # outer PID + ILC part of the setpoint, bar

    # -- commands (loop thread, not the tick) --------------------------------------------
    def model_value(self) -> float:
        """The model's pressure at the present targets and measurements (0 without one)."""
        m = self.m
        if self.ff is None or not self.use_ff:
            return 0.0
        ln = m.target_length
        x = (m.length0_mm - ln) / m.length0_mm
        f = self.force_lp if self.position else m.target_force
        return self.ff.pressure(f, ln, x, self.target_vel.value)

    def enter(self, mode: Mode, use_ff: bool, ilc: bool) -> None:
        """Switch the muscle into a length mode, bumpless: targets at the present length
        and force, the outer loop's integral (or the fading offset) holding the present
        setpoint."""
        m = self.m
        m.profile = None
        was = m.mode
        if was == Mode.PRESSURE:
            m.target_length = m.length
            m.target_force = m.force
            self.target_vel.reset(m.length, 0.0)
            self.force_lp = m.force
            self.sp_rate.reset(m.sp, 0.0)
        self.position = mode == Mode.POSITION
        self.use_ff = use_ff
        self.ilc_on = ilc and self.position
        self.ilc = None
        m.mode = mode
        ff = self.model_value()
        self.pid.reset(-m.length)
        self.bump = 0.0
        if self.position:
            self.pid.i = max(-self.pid.integral_limit, min(self.pid.integral_limit, m.sp - ff))
        else:
            self.bump = m.sp - ff
        self.last_sp = m.sp
        m.feedforward = ff
        m.length_ctl_on = True

    def leave(self) -> None:
        """Back to pressure mode; the setpoint stays where it is (bumpless)."""
        m = self.m
        m.mode = Mode.PRESSURE
        m.length_ctl_on = False
        m.profile = None
        m.sp_rate = 0.0
        m.feedforward = 0.0
        m.target_length = m.target_force = math.nan
        self.ilc = None

    def swap(self, ff: Feedforward) -> float:
        """A new model while running: the outer integral (or the fading offset) takes up
        the difference between the old and the new model's pressure. Returns it (bar)."""
        before = self.model_value() if self.m.length_ctl_on else 0.0
        self.ff = ff
        self.target_vel.window_s = ff.velocity_window_s
        if not self.m.length_ctl_on:
            return 0.0
        diff = before - self.model_value()
        if self.position:
            il = self.pid.integral_limit
            self.pid.i = max(-il, min(il, self.pid.i + diff))
        else:
            self.bump += diff
        return diff

    def start_ilc(self, period_s: float) -> None:
        c = self.cfg.ilc
        self.ilc = Ilc(period_s, c.gain_bar_per_mm, c.gain_d_bar_s_per_mm, c.lead_s,
                       c.forgetting, c.limit_bar, c.resolution_s)

    # -- the tick --------------------------------------------------------------------------
    def step(self, now: float, dt: float, state: int, sp_prev: float) -> float:
        """The pressure setpoint for this tick (bar); sets the muscle's target_length,
        feedforward and sp_rate, and `flags` (FF_CLIPPED, SLEW_LIMITED)."""
        m = self.m
        flags = 0
        l0 = m.length0_mm
        prof = m.profile
        if prof is not None and (state == S_RUNNING or state == S_LOAD):
            prof.sample(now)
            x_t = prof.value
            ln_t = l0 * (1.0 - x_t)
            m.target_length = ln_t
        else:
            ln_t = m.target_length
            x_t = (l0 - ln_t) / l0
        v_t = self.target_vel.update(ln_t, dt)
        f_in = m.target_force
        if self.position:
            f = m.force
            fl = self.force_lp
            f_in = self.force_lp = fl + dt / (self.force_tau_s + dt) * (f - fl) if (
                fl == fl) else f
        ff = 0.0
        if self.use_ff and self.ff is not None:
            ff_obj = self.ff
            ff = ff_obj.pressure(f_in, ln_t, x_t, v_t)
            if ff_obj.clipped:
                flags |= F_CLIP
        want = ff
        pid = self.pid
        i_before = pid.i
        if self.position:
            length = m.length
            corr = pid.step(length - ln_t, -length, dt)
            ilc = self.ilc
            if ilc is not None and prof is not None and not prof.done and (
                    state == S_RUNNING or state == S_LOAD):
                tau = now - prof.t0_s - prof.lead_in_s
                if tau >= 0.0:
                    corr += ilc.step(tau, length - ln_t, dt)
            self.correction = corr
            want += corr
        else:
            b = self.bump
            if b != 0.0:
                b -= b * dt / (self.bump_tau_s + dt)
                self.bump = b if abs(b) > 1e-6 else 0.0
                want += b
        held = False
        if want != want:  # a NaN input (stale sensor): hold; the fault follows
            want = sp_prev
            held = True
        hi = m.max_p
        if want > hi:
            want, held = hi, True
        elif want < 0.0:
            want, held = 0.0, True
        step = m.slew * dt
        if want > sp_prev + step:
            want, held = sp_prev + step, True
            flags |= F_SLEW
        elif want < sp_prev - step:
            want, held = sp_prev - step, True
            flags |= F_SLEW
        if held or sp_prev != self.last_sp:  # clamped here or by the tick's soft limits
            pid.i = i_before
        m.feedforward = ff
        m.sp_rate = self.sp_rate.update(want, dt)
        self.last_sp = want
        self.flags = flags
        return want


# -- length targets (commands) ---------------------------------------------------------------
def contraction_bounds(m: Any) -> tuple[float, float]:
    """The contraction range a length target may use: inside the soft limits, where
    the tick's limit guards would start to fight the target."""
    return -m.max_stretch + m.safety.soft_band_contraction, m.soft_c


def check_contraction(m: Any, what: str, *values: float) -> None:
    lo, hi = contraction_bounds(m)
    for v in values:
        if not lo - 1e-12 <= v <= hi + 1e-12:
            raise CommandRefused(
                f"{m.name}: {what} {100 * v:.2f} % contraction is outside the allowed "
                f"{100 * lo:.2f} % to {100 * hi:.2f} % (soft limits: {100 * m.max_c:.1f} % "
                f"contraction, {100 * m.max_stretch:.1f} % stretch, less the soft band)")


def check_reachable(m: Any, *values: float, margin: float = REACH_MARGIN) -> None:
    """Refuse length targets the hanging load does not let the muscle reach between 0 bar
    and its pressure limit (by the static force model, with a margin)."""
    fm, load = m.force_model, m.load_kg
    x_hi = equilibrium_contraction(fm, m.max_p, load)
    x_lo = equilibrium_contraction(fm, 0.0, load)
    for v in values:
        if v > x_hi - margin:
            raise CommandRefused(
                f"{m.name}: with {load:g} kg the muscle reaches about {100 * x_hi:.1f} % "
                f"contraction at {m.max_p:g} bar (static force model); {100 * v:.1f} % needs "
                f"at most {100 * (x_hi - margin):.1f} %")
        if v < x_lo + margin:
            raise CommandRefused(
                f"{m.name}: with {load:g} kg the muscle hangs at about {100 * x_lo:.1f} % "
                f"contraction at 0 bar; {100 * v:.1f} % would need pushing (at least "
                f"{100 * (x_lo + margin):.1f} %)")


def length_profile(m: Any, now: float, kind: str, *, min_contraction: float | None,
                   max_contraction: float | None, to_contraction: float | None,
                   freq_hz: float, cycles: int | None, rate_per_s: float | None,
                   rise_s: float | None, duration_s: float | None,
                   lead_in_per_s: float | None) -> Profile:
    """A length profile for muscle `m`, in contraction (fraction) units, checked against
    the contraction limits and the length rate limit before anything moves."""
    max_rate = m.length_ctl.cfg.max_rate_per_s
    if kind in ("sine", "triangle", "step"):
        if min_contraction is None or max_contraction is None:
            raise CommandRefused(f"{kind} length profile: give min_contraction and "
                                 "max_contraction (fractions, e.g. 0.05 and 0.20)")
        if not max_contraction > min_contraction:
            raise CommandRefused(f"{kind} length profile: max_contraction "
                                 f"({max_contraction}) must exceed min_contraction "
                                 f"({min_contraction})")
        check_contraction(m, f"{kind} profile spans to", min_contraction, max_contraction)
    elif kind in ("ramp", "constant"):
        if to_contraction is None:
            raise CommandRefused(f"{kind} length profile: give to_contraction")
        check_contraction(m, f"{kind} profile target", to_contraction)
    else:
        raise CommandRefused(f"unknown profile kind {kind!r}; use constant, step, ramp, sine "
                             "or triangle")
    check_reachable(m, *(v for v in (min_contraction, max_contraction, to_contraction)
                         if v is not None))
    lead = lead_in_per_s if lead_in_per_s is not None else 0.5 * max_rate
    if not 0 < lead <= max_rate:
        raise CommandRefused(f"lead-in rate must be in (0, {max_rate:g}] contraction/s "
                             "(control.position.max_rate_per_s)")
    spec = ProfileSpec(kind=kind,  # type: ignore[arg-type]
                       min_bar=min_contraction if min_contraction is not None else 0.0,
                       max_bar=max_contraction if max_contraction is not None else 0.0,
                       freq_hz=freq_hz, cycles=cycles, to_bar=to_contraction,
                       rate_bar_per_s=rate_per_s, rise_s=rise_s, duration_s=duration_s,
                       lead_in_bar_per_s=lead)
    # ProfileSpec is unit-free arithmetic; here its "bar" fields hold contraction.
    rate = spec.shape_max_rate(max_rate)
    if rate > max_rate * (1 + 1e-9):
        raise CommandRefused(
            f"{kind} length profile needs {rate:.3g} contraction/s ({rate * m.length0_mm:.3g} "
            f"mm/s) but the limit is {max_rate:g}/s (control.position.max_rate_per_s); "
            "lower freq_hz or the span")
    if cycles is not None and cycles < 1:
        raise CommandRefused("cycles must be at least 1")
    x_now = (m.length0_mm - m.target_length) / m.length0_mm
    return Profile(spec, now, x_now, max_rate)


def check_length_profile_config(cfg: Any, muscle: str, payload: dict[str, Any]) -> None:
    """`length_profile`'s checks from the config alone (limits, load, rate), for a
    profile asked for before the rig starts (`pamd run --mode position --profile`)."""
    from types import SimpleNamespace

    from pamd.muscle import force_model

    mc, lim, saf = cfg.muscle(muscle), cfg.limits[muscle], cfg.rig.safety
    view = SimpleNamespace(  # the attributes of a MuscleController that the checks read
        name=muscle, max_stretch=lim.max_pretension, safety=saf, max_c=lim.max_contraction,
        soft_c=lim.max_contraction - saf.soft_band_contraction,
        length0_mm=mc.nominal_length_mm, target_length=mc.nominal_length_mm,
        force_model=force_model(mc.force_model), load_kg=mc.load_kg,
        max_p=lim.max_pressure_bar, length_ctl=SimpleNamespace(cfg=cfg.rig.control.position))
    length_profile(view, 0.0, payload.get("kind", "sine"),
                   min_contraction=payload.get("min_contraction"),
                   max_contraction=payload.get("max_contraction"),
                   to_contraction=payload.get("to_contraction"),
                   freq_hz=payload.get("freq_hz", 0.05), cycles=payload.get("cycles"),
                   rate_per_s=payload.get("rate_per_s"), rise_s=payload.get("rise_s"),
                   duration_s=payload.get("duration_s"),
                   lead_in_per_s=payload.get("lead_in_per_s"))

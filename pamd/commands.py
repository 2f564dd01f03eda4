"""Commands to the running loop: their argument schemas and what each one does.

`parse_command` checks a payload's shape (unknown fields, types, NaN) and can run
anywhere (the io process does it before anything reaches the loop).
`apply_command` runs in the loop's thread at the start of a tick, checks the
command against the present state and limits, and returns the verdict. A refused
command changes nothing.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pamd.config.engine import Context, build_dataclass, spec
from pamd.control.profiles import Profile, ProfileSpec
from pamd.drivers.safe_outputs import push_safe_outputs
from pamd.errors import CommandRefused
from pamd.muscle import MUSCLE_TYPES
from pamd.tick import State


@dataclass(frozen=True, kw_only=True)
class SetpointArgs:
    muscle: str = spec(doc="Muscle name.")
    bar: float | None = spec(None, "Pressure setpoint (pressure mode).", unit="bar")
    length_mm: float | None = spec(None, "Length target (length_force and position modes).",
                                   unit="mm", gt=0.0)
    force_n: float | None = spec(None, "Force target (length_force mode; default: the force "
                                 "at the mode change).", unit="N", min=0.0)
    ramp_s: float | None = spec(None, "Reach the setpoint over this time (default: at half "
                                "the slew limit, or half control.position.max_rate_per_s "
                                "for a length).", unit="s", min=0.0)
    deadman_s: float | None = spec(None, "Streamed setpoints: unless the next setpoint for "
                                   "this muscle arrives within this time, the rig goes to "
                                   "the safe state (a later setpoint without it disarms "
                                   "it).", unit="s", gt=0.0)


@dataclass(frozen=True, kw_only=True)
class ProfileArgs:
    muscle: str | None = spec(None, "Muscle name (default: every muscle).")
    kind: str = spec("sine", "constant, step, ramp, sine or triangle.")
    min_bar: float = spec(0.0, "Lowest pressure.", unit="bar")
    max_bar: float = spec(6.0, "Highest pressure.", unit="bar")
    freq_hz: float = spec(0.05, "Frequency (sine, triangle, step).", unit="Hz")
    cycles: int | None = spec(None, "Number of cycles (default: until stopped).", min=1)
    to_bar: float | None = spec(None, "Target (ramp, constant).", unit="bar")
    rate_bar_per_s: float | None = spec(None, "Ramp rate.", unit="bar/s", gt=0.0)
    rise_s: float | None = spec(None, "Step edge duration.", unit="s", gt=0.0)
    duration_s: float | None = spec(None, "Duration (constant).", unit="s", gt=0.0)
    lead_in_bar_per_s: float = spec(1.0, "Lead-in ramp rate from the present pressure.",
                                    unit="bar/s", gt=0.0)
    # Length profiles (length_force and position modes), in contraction (fraction of the
    # nominal length); the *_bar fields above do not apply to them.
    min_contraction: float | None = spec(None, "Length profile: least contraction (sine, "
                                         "triangle, step), e.g. 0.05.")
    max_contraction: float | None = spec(None, "Length profile: most contraction, e.g. 0.20.")
    to_contraction: float | None = spec(None, "Length profile: target (ramp, constant).")
    rate_per_s: float | None = spec(None, "Length profile: ramp rate, contraction per second.",
                                    unit="1/s", gt=0.0)
    lead_in_per_s: float | None = spec(None, "Length profile: lead-in rate from the present "
                                       "target (default: half control.position."
                                       "max_rate_per_s).", unit="1/s", gt=0.0)


LENGTH_PROFILE_FIELDS = ("min_contraction", "max_contraction", "to_contraction", "rate_per_s",
                         "lead_in_per_s")


@dataclass(frozen=True, kw_only=True)
class ModeArgs:
    muscle: str | None = spec(None, "Muscle name (default: every muscle).")
    mode: str = spec(doc="pressure, length_force or position.")
    feedforward: bool = spec(True, "position: use the muscle's model (false: the position "
                             "PID alone, no model needed).")
    ilc: bool = spec(False, "position: learn a correction over the cycles of a periodic "
                     "length profile (iterative learning control).")


@dataclass(frozen=True, kw_only=True)
class ModelArgs:
    muscle: str = spec(doc="Muscle name.")
    file: str = spec(doc="Model file (pamd train) on the rig PC; read, checked and compiled "
                     "before the command reaches the loop.")


class PreparedModelArgs:
    """A `model` command whose file was loaded, checked and compiled outside the loop's
    thread (`prepare_command`); the loop only swaps `feedforward` in."""

    def __init__(self, muscle: str, file: str, feedforward: Any) -> None:
        self.muscle, self.file, self.feedforward = muscle, file, feedforward

    def describe(self) -> dict[str, Any]:
        return {"muscle": self.muscle, **self.feedforward.describe()}


@dataclass(frozen=True, kw_only=True)
class MuscleArgs:
    muscle: str | None = spec(None, "Muscle name (default: every muscle).")


@dataclass(frozen=True, kw_only=True)
class HomeArgs:
    muscle: str = spec(doc="Muscle name.")
    length_mm: float = spec(doc="The muscle's true length at its present position.", unit="mm",
                            gt=0.0)


@dataclass(frozen=True, kw_only=True)
class LoadArgs:
    muscle: str = spec(doc="Muscle name.")
    load_kg: float = spec(doc="The hanging load now on the muscle.", unit="kg", min=0.0)


@dataclass(frozen=True, kw_only=True)
class NoArgs:
    pass


@dataclass(frozen=True, kw_only=True)
class CollectArgs:
    plan_file: str = spec(doc="Experiment plan (YAML) on the rig PC.")
    start_step: int = spec(0, "Start at this step (0-based; --resume).", min=0)


@dataclass(frozen=True, kw_only=True)
class EstopArgs:
    reason: str = spec("emergency stop", "Why (recorded).")


@dataclass(frozen=True, kw_only=True)
class MuscleSettings:
    """One muscle's share of a reloaded config, computed outside the loop's thread
    (`pamd.service.reload`); the loop only assigns it (`MuscleController.apply_settings`).
    """

    muscle: str
    pid: Any  # PidConfig
    rate_feedforward_s: float
    pressure_timeout_s: float
    force_timeout_s: float
    length_timeout_s: float
    safety: Any  # SafetyConfig
    limits: Any  # MuscleLimitsResolved
    slew_limit_bar_per_s: float
    nominal_length_mm: float
    load_kg: float | None  # None: unchanged in the file (a `load` command's value stays)


@dataclass(frozen=True, kw_only=True)
class ReloadArgs:
    """The `reload` command (SIGHUP). Internal: not in VERBS, so no client can send
    it; the daemon builds it from a validated config. `plan` (one MuscleSettings per
    muscle, in the rig's order) stays out of the recorded event, like collect's."""

    config_sha256: str
    at_once: tuple[str, ...]  # changed key paths that apply at once (gains, timeouts)
    idle_only: tuple[str, ...]  # changed key paths that apply only while IDLE (limits)
    startup_timeout_s: float
    plan: tuple[MuscleSettings, ...]


VERBS: dict[str, type] = {
    "setpoint": SetpointArgs, "profile": ProfileArgs, "hold": NoArgs, "resume": NoArgs,
    "stop": NoArgs, "estop": EstopArgs, "reset": NoArgs, "home": HomeArgs, "tare": MuscleArgs,
    "load": LoadArgs, "confirm": NoArgs, "pause": NoArgs, "collect": CollectArgs,
    "mode": ModeArgs, "model": ModelArgs,
}


@dataclass
class Command:
    """A parsed command on its way to the loop; `reply` receives the verdict."""

    verb: str
    args: Any
    reply: Callable[[dict[str, Any]], None] | None = None
    sender: str = "local"
    user: str = ""


def parse_command(verb: str, payload: Any, sender: str = "local", user: str = "",
                  reply: Callable[[dict[str, Any]], None] | None = None) -> Command:
    """Shape checks only; raises CommandRefused saying what was wrong."""
    if verb not in VERBS:
        raise CommandRefused(f"unknown command {verb!r}; known: {', '.join(VERBS)}")
    if payload is None:
        payload = {}
    if not isinstance(payload, dict):
        raise CommandRefused(f"{verb}: the payload must be a JSON object")
    ctx = Context(f"cmd/{verb}")
    args = build_dataclass(VERBS[verb], payload, ctx, "", None)
    if ctx.issues:
        raise CommandRefused("; ".join(
            f"{i.path}: expected {i.expected}" + (f", found {i.found}" if i.found else "")
            for i in ctx.issues))
    return Command(verb, args, reply, sender, user)


def prepare_command(cmd: Command, cfg: Any) -> Command:
    """The part of a command that is I/O, done outside the loop's thread before it is
    queued: a `model` command's file is read, checked against the muscle and compiled
    here (CommandRefused if it cannot be), so the loop only swaps the compiled object."""
    if cmd.verb != "model" or isinstance(cmd.args, PreparedModelArgs):
        return cmd
    from pamd.control.feedforward import Feedforward
    from pamd.errors import ModelError

    a = cmd.args
    try:
        mcfg = cfg.muscle(a.muscle)
    except KeyError:
        names = ", ".join(m.name for m in cfg.rig.muscles)
        raise CommandRefused(f"no muscle named {a.muscle!r}; muscles: {names}") from None
    path = os.path.abspath(os.path.expanduser(a.file))
    try:
        ff = Feedforward.from_file(path, mcfg, cfg.limits[a.muscle])
    except ModelError as exc:
        raise CommandRefused(f"model refused: {exc}") from None
    return dataclasses.replace(cmd, args=PreparedModelArgs(a.muscle, path, ff))


def apply_command(ctrl: Any, cmd: Command) -> dict[str, Any]:
    """Apply in the loop's thread; returns the verdict."""
    try:
        result = _HANDLERS[cmd.verb](ctrl, cmd.args)
    except CommandRefused as exc:
        verdict: dict[str, Any] = {"ok": False, "error": str(exc)}
    else:
        verdict = {"ok": True, **(result or {})}
    describe = getattr(cmd.args, "describe", None)  # prepared args say what they hold
    args = describe() if describe is not None else {
        k: v for k, v in vars(cmd.args).items() if k != "plan"}
    ctrl.sink.event(ctrl.now, "command", {"verb": cmd.verb, "args": args,
                                         "sender": cmd.sender, "user": cmd.user, **verdict})
    return verdict


def _muscles(ctrl: Any, name: str | None) -> list[Any]:
    if name is None:
        return list(ctrl.muscles)
    if name not in ctrl.by_name:
        raise CommandRefused(f"no muscle named {name!r}; muscles: {', '.join(ctrl.by_name)}")
    return [ctrl.by_name[name]]


def _can_move(ctrl: Any) -> None:
    st = ctrl.supervisor.state
    if st == State.STARTING:
        raise CommandRefused("the rig is starting (sensors not yet read); try again shortly")
    if ctrl.supervisor.latched:
        raise CommandRefused(f"the rig is in {st.name} ({ctrl.supervisor.reason}); send reset "
                             "once the cause is gone")


def _need_reference(ms: list[Any]) -> None:
    for m in ms:
        if not m.referenced:
            raise CommandRefused(f"{m.name}: length not referenced, so contraction limits "
                                 "cannot be enforced; send home first")


def _start(ctrl: Any, ms: list[Any], spec_: ProfileSpec) -> float | None:
    for m in ms:
        spec_.check(0.0, m.max_p, m.slew)
    total = None
    for m in ms:
        m.start_profile(Profile(spec_, ctrl.now, m.sp, m.slew))
        total = m.profile.total_s()
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"{spec_.kind} profile started")
    return total


def _setpoint(ctrl: Any, a: SetpointArgs) -> dict[str, Any]:
    _can_move(ctrl)
    ms = _muscles(ctrl, a.muscle)
    _need_reference(ms)
    m = ms[0]
    if m.length_ctl_on or a.bar is None:
        out = _length_setpoint(ctrl, m, a)
        ctrl.arm_deadman(m, a.deadman_s)
        return dict(out, deadman_s=a.deadman_s)
    if a.length_mm is not None or a.force_n is not None:
        raise CommandRefused(f"{m.name} is in pressure mode: length_mm and force_n are "
                             "targets of the length_force and position modes (send mode "
                             "first); give bar alone")
    if not 0.0 <= a.bar <= m.max_p:
        raise CommandRefused(f"{m.name}: {a.bar:g} bar is outside 0-{m.max_p:g} bar")
    dist = abs(a.bar - m.sp)
    rate = 0.5 * m.slew if not a.ramp_s else dist / a.ramp_s
    if rate > m.slew:
        raise CommandRefused(f"{m.name}: reaching {a.bar:g} bar in {a.ramp_s:g} s needs "
                             f"{rate:.3g} bar/s, above the slew limit {m.slew:g} bar/s")
    spec_ = ProfileSpec(kind="ramp", to_bar=a.bar, rate_bar_per_s=max(rate, 1e-6),
                        lead_in_bar_per_s=m.slew)
    m.start_profile(Profile(spec_, ctrl.now, m.sp, m.slew))
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"setpoint {m.name} {a.bar:g} bar")
    ctrl.arm_deadman(m, a.deadman_s)  # streamed setpoints: each one re-arms (or disarms)
    return {"muscle": m.name, "bar": a.bar, "ramp_s": dist / rate if rate > 0 else 0.0,
            "deadman_s": a.deadman_s}


def _profile(ctrl: Any, a: ProfileArgs) -> dict[str, Any]:
    _can_move(ctrl)
    ms = _muscles(ctrl, a.muscle)
    _need_reference(ms)
    if any(m.length_ctl_on for m in ms) or any(
            getattr(a, k) is not None for k in LENGTH_PROFILE_FIELDS):
        return _length_profile(ctrl, ms, a)
    fields = dataclasses.asdict(a)
    fields.pop("muscle")
    for k in LENGTH_PROFILE_FIELDS:
        fields.pop(k)
    if fields["kind"] not in ("constant", "step", "ramp", "sine", "triangle"):
        raise CommandRefused(f"unknown profile kind {a.kind!r}; use constant, step, ramp, "
                             "sine or triangle")
    total = _start(ctrl, ms, ProfileSpec(**fields))
    return {"duration_s": total}


def _length_setpoint(ctrl: Any, m: Any, a: SetpointArgs) -> dict[str, Any]:
    """A length (and force) target in the length modes, reached by a ramp."""
    from pamd.control.feedforward import length_profile
    from pamd.tick import Mode

    mode = m.mode.name.lower()
    if not m.length_ctl_on:
        raise CommandRefused(f"{m.name}: give bar, the pressure setpoint (length_mm and "
                             "force_n are targets of the length_force and position modes; "
                             "send mode first)")
    if a.bar is not None:
        raise CommandRefused(f"{m.name} is in {mode} mode: give length_mm (and force_n), not "
                             "bar; send mode pressure for pressure setpoints")
    if a.force_n is not None and m.mode != Mode.LENGTH_FORCE:
        raise CommandRefused(f"{m.name}: force_n is a target only in length_force mode (the "
                             f"{mode} mode feeds the model the measured force)")
    if a.length_mm is None and a.force_n is None:
        raise CommandRefused(f"{m.name}: give length_mm" + (
            " and/or force_n" if m.mode == Mode.LENGTH_FORCE else ""))
    rated = MUSCLE_TYPES[m.cfg.type].theoretical_force_n
    if a.force_n is not None and a.force_n > rated:
        raise CommandRefused(f"{m.name}: {a.force_n:g} N exceeds the {m.cfg.type}'s "
                             f"theoretical force ({rated:g} N)")
    out: dict[str, Any] = {"muscle": m.name, "mode": mode}
    if a.length_mm is not None:
        l0 = m.length0_mm
        x = (l0 - a.length_mm) / l0
        max_rate = m.length_ctl.cfg.max_rate_per_s
        dist = abs(x - (l0 - m.target_length) / l0)
        rate = 0.5 * max_rate if not a.ramp_s else dist / a.ramp_s
        if rate > max_rate:
            raise CommandRefused(
                f"{m.name}: reaching {a.length_mm:g} mm in {a.ramp_s:g} s needs "
                f"{rate * l0:.3g} mm/s, above the length rate limit {max_rate * l0:.3g} mm/s "
                "(control.position.max_rate_per_s)")
        prof = length_profile(m, ctrl.now, "ramp", min_contraction=None, max_contraction=None,
                              to_contraction=x, freq_hz=1.0, cycles=None,
                              rate_per_s=max(rate, 1e-6), rise_s=None, duration_s=None,
                              lead_in_per_s=max_rate)
        m.profile = prof
        out.update(length_mm=a.length_mm, ramp_s=dist / rate if rate > 0 else 0.0)
    if a.force_n is not None:
        m.target_force = a.force_n
        out["force_n"] = a.force_n
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"setpoint {m.name} " + ", ".join(
        f"{k} {v:g}" for k, v in out.items() if k in ("length_mm", "force_n")))
    return out


def _length_profile(ctrl: Any, ms: list[Any], a: ProfileArgs) -> dict[str, Any]:
    """A length profile (contraction units) on muscles in a length mode."""
    from pamd.control.feedforward import length_profile

    for m in ms:
        if not m.length_ctl_on:
            raise CommandRefused(f"{m.name} is in pressure mode: a length profile "
                                 "(min/max/to_contraction) needs mode length_force or position "
                                 "first")
    profiles = [length_profile(m, ctrl.now, a.kind, min_contraction=a.min_contraction,
                               max_contraction=a.max_contraction,
                               to_contraction=a.to_contraction, freq_hz=a.freq_hz,
                               cycles=a.cycles, rate_per_s=a.rate_per_s, rise_s=a.rise_s,
                               duration_s=a.duration_s, lead_in_per_s=a.lead_in_per_s)
                for m in ms]  # every muscle checked before any moves
    total = None
    for m, prof in zip(ms, profiles, strict=True):
        m.profile = prof
        lc = m.length_ctl
        if lc.ilc_on and prof.period_s > 0:
            lc.start_ilc(prof.period_s)
        total = prof.total_s()
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"{a.kind} length profile started")
    return {"duration_s": total, "length_profile": True}


def _mode(ctrl: Any, a: ModeArgs) -> dict[str, Any]:
    from pamd.control.feedforward import MODE_NAMES
    from pamd.tick import Mode

    _can_move(ctrl)
    if a.mode not in MODE_NAMES:
        raise CommandRefused(f"unknown mode {a.mode!r}; use {', '.join(MODE_NAMES)}")
    seq = getattr(ctrl, "sequencer", None)
    if seq is not None and not seq.outcome:
        raise CommandRefused("an experiment plan is running; its profiles are pressure "
                             "profiles (pause or stop it first)")
    ms = _muscles(ctrl, a.muscle)
    mode = MODE_NAMES[a.mode]
    if mode == Mode.PRESSURE:
        for m in ms:
            if m.length_ctl_on:
                m.length_ctl.leave()
        return {"mode": a.mode, "muscles": [m.name for m in ms]}
    if a.ilc and mode != Mode.POSITION:
        raise CommandRefused("ilc: iterative learning runs in position mode only")
    if not a.feedforward and mode != Mode.POSITION:
        raise CommandRefused("length_force mode is the model itself: feedforward cannot be "
                             "off")
    _need_reference(ms)
    for m in ms:
        if a.feedforward and m.length_ctl.ff is None:
            raise CommandRefused(
                f"{m.name}: no model for {a.mode} mode; name model_file in the config, `pamd "
                "run --model FILE` or send the model command first (position mode with "
                "feedforward false runs the position PID alone)")
        if not (math.isfinite(m.length) and math.isfinite(m.force)):
            raise CommandRefused(f"{m.name}: no length/force reading to start from")
    for m in ms:
        m.length_ctl.enter(mode, a.feedforward, a.ilc)
    return {"mode": a.mode, "muscles": [m.name for m in ms],
            "feedforward_bar": {m.name: m.feedforward for m in ms}}


def _model(ctrl: Any, a: Any) -> dict[str, Any]:
    """Swap in a model compiled outside the loop (`prepare_command`)."""
    if not isinstance(a, PreparedModelArgs):
        raise CommandRefused("model: the file was not loaded (send the command through the "
                             "daemon, which reads and checks it outside the loop)")
    m = _muscles(ctrl, a.muscle)[0]
    diff = m.length_ctl.swap(a.feedforward)
    return {**a.describe(), "mode": m.mode.name.lower(), "taken_up_bar": diff}


def _hold(ctrl: Any, a: NoArgs) -> dict[str, Any]:
    _can_move(ctrl)
    ctrl.hold_started = ctrl.now
    ctrl.supervisor.go(ctrl.now, State.HOLD, "hold: setpoints frozen")
    return {}


def _resume(ctrl: Any, a: NoArgs) -> dict[str, Any]:
    if ctrl.supervisor.state != State.HOLD:
        raise CommandRefused(f"resume only from HOLD (state is {ctrl.supervisor.state.name})")
    paused = ctrl.now - getattr(ctrl, "hold_started", ctrl.now)
    seq = ctrl.sequencer
    running = seq is not None and not seq.outcome
    for m in ctrl.muscles:
        if m.profile is not None:
            m.profile.t0_s += paused
            running = True
    if seq is not None:
        seq.awaiting_operator = "" if seq.phase == "pause" else seq.awaiting_operator
    ctrl.supervisor.go(ctrl.now, State.RUNNING if running else State.IDLE, "resumed")
    return {}


def _stop(ctrl: Any, a: NoArgs) -> dict[str, Any]:
    if ctrl.supervisor.latched:
        raise CommandRefused(f"the rig is already in {ctrl.supervisor.state.name}, at its safe "
                             "state")
    ctrl.go_safe("stop: ramping to the safe state")
    return {}


def _estop(ctrl: Any, a: EstopArgs) -> dict[str, Any]:
    for m in ctrl.muscles:
        m.profile = None
    ctrl.supervisor.estop(ctrl.now, f"emergency stop: {a.reason}")
    return {}


def _reset(ctrl: Any, a: NoArgs) -> dict[str, Any]:
    sup = ctrl.supervisor
    if not sup.latched:
        raise CommandRefused(f"nothing to reset: the rig is {sup.state.name}")
    for m in ctrl.muscles:
        if m.started:
            missing = m.inputs_fresh(ctrl.now)
            if missing is not None:
                raise CommandRefused(f"cannot reset: {missing} still has no fresh reading")
    for drv in ctrl.drivers:
        if drv.fault is not None:
            raise CommandRefused(f"cannot reset: driver {drv.name!r} still reports {drv.fault}")
    for m in ctrl.muscles:
        if m.started:
            m.pid.reset(m.pressure)
            m.safing = False
        else:
            m.hold_measured()
    sup.reset(ctrl.now)
    return {}


def _idle_or_hold(ctrl: Any, verb: str) -> None:
    if ctrl.supervisor.state not in (State.IDLE, State.HOLD, State.FAULT):
        raise CommandRefused(f"{verb} only while IDLE, HOLD or FAULT (state is "
                             f"{ctrl.supervisor.state.name})")


def _home(ctrl: Any, a: HomeArgs) -> dict[str, Any]:
    _idle_or_hold(ctrl, "home")
    m = _muscles(ctrl, a.muscle)[0]
    raw_len = m.length - m.ref.length_offset_mm
    if not math.isfinite(raw_len):
        raise CommandRefused(f"{m.name}: no length reading to reference")
    m.ref.length_offset_mm = a.length_mm - raw_len  # at once, in software
    b = m.sig.length
    counts = b.driver.preset_counts
    if b.driver.preset_input(b.index, (a.length_mm - b.offset) / b.gain):
        # The device takes the reference too; the tick drops the software offset
        # when the device confirms (preset count moves).
        m.pending_preset = (counts, b.index, counts[b.index])
    m.ref.length_referenced = True
    m.ref.homed_at = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    m._prev_len = math.nan
    ctrl.calibration_dirty = True  # saved outside the loop's thread
    return {"muscle": m.name, "length_offset_mm": m.ref.length_offset_mm}


def _tare(ctrl: Any, a: MuscleArgs) -> dict[str, Any]:
    _idle_or_hold(ctrl, "tare")
    out = {}
    for m in _muscles(ctrl, a.muscle):
        raw = m.force + m.ref.force_offset_n
        if not math.isfinite(raw):
            raise CommandRefused(f"{m.name}: no force reading to tare")
        m.ref.force_offset_n = raw
        m.ref.tared_at = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        out[m.name] = raw
    ctrl.calibration_dirty = True  # saved outside the loop's thread
    return {"force_offset_n": out}


def _load(ctrl: Any, a: LoadArgs) -> dict[str, Any]:
    m = _muscles(ctrl, a.muscle)[0]
    rated = MUSCLE_TYPES[m.cfg.type].max_load_kg
    if a.load_kg > rated:
        raise CommandRefused(f"{m.name}: {a.load_kg:g} kg exceeds the {m.cfg.type} rating "
                             f"({rated:g} kg)")
    m.update_load(a.load_kg)
    push_safe_outputs(ctrl)  # modules with a comm watchdog hold the new safe state
    return {"muscle": m.name, "load_kg": a.load_kg, "safe_pressure_bar": m.safe_bar}


def _confirm(ctrl: Any, a: NoArgs) -> dict[str, Any]:
    seq = ctrl.sequencer
    if seq is None or seq.outcome:
        raise CommandRefused("no experiment is running")
    try:
        return {"message": seq.confirm_load()}
    except ValueError as exc:
        raise CommandRefused(str(exc)) from None


def _pause(ctrl: Any, a: NoArgs) -> dict[str, Any]:
    seq = ctrl.sequencer
    if seq is None or seq.outcome:
        raise CommandRefused("no experiment is running (use hold to freeze setpoints)")
    seq.pause_at_cycle_end = True
    return {"message": "pausing at the end of the present cycle"}


def _collect(ctrl: Any, a: Any) -> dict[str, Any]:
    """`a.plan` is a Plan already read and checked outside the loop's thread."""
    from pamd.experiment.sequencer import Sequencer

    _can_move(ctrl)
    if ctrl.sequencer is not None and not ctrl.sequencer.outcome:
        raise CommandRefused(f"plan {ctrl.sequencer.plan.name!r} is still running")
    plan = getattr(a, "plan", None)
    if plan is None:
        raise CommandRefused("collect: the plan was not loaded (pass it through the daemon)")
    _need_reference([ctrl.by_name[plan.muscle]])
    if ctrl.by_name[plan.muscle].length_ctl_on:
        raise CommandRefused(f"{plan.muscle} is in a length mode and plans run pressure "
                             "profiles; send mode pressure first")
    if not 0 <= a.start_step < len(plan.steps):
        raise CommandRefused(f"start_step {a.start_step} is not a step of the plan "
                             f"(0-{len(plan.steps) - 1})")
    ctrl.sequencer = Sequencer(plan, ctrl, a.start_step)
    return {"plan": plan.name, "steps": len(plan.steps), "start_step": a.start_step}


def _reload(ctrl: Any, a: ReloadArgs) -> dict[str, Any]:
    """A reloaded config: gains and timeouts at once; limits, slew, loads and nominal
    lengths only while IDLE (otherwise reported as deferred: the daemon sends the
    command again once the rig is IDLE). Refused as a whole, changing nothing, if
    a held pressure is above a new pressure limit."""
    settings = a.plan
    if [s.muscle for s in settings] != [m.name for m in ctrl.muscles]:
        raise CommandRefused("reload: the muscles differ from the running rig's; that "
                             "needs a restart")
    with_limits = bool(a.idle_only) and ctrl.supervisor.state == State.IDLE
    if with_limits:
        for m, s in zip(ctrl.muscles, settings, strict=True):
            if m.started and m.sp > s.limits.max_pressure_bar:
                raise CommandRefused(
                    f"reload: {m.name} holds {m.sp:.2f} bar, above the new pressure limit "
                    f"{s.limits.max_pressure_bar:g} bar; lower the setpoint first "
                    "(nothing changed)")
    for m, s in zip(ctrl.muscles, settings, strict=True):
        m.apply_settings(s, with_limits)
    ctrl.startup_timeout_s = a.startup_timeout_s
    if with_limits:
        push_safe_outputs(ctrl)  # loads or limits may have moved the safe pressures
    return {"applied": list(a.at_once) + (list(a.idle_only) if with_limits else []),
            "deferred": [] if with_limits else list(a.idle_only),
            "state": ctrl.supervisor.state.name}


_HANDLERS: dict[str, Callable[[Any, Any], dict[str, Any] | None]] = {
    "mode": _mode, "model": _model,
    "setpoint": _setpoint, "profile": _profile, "hold": _hold, "resume": _resume,
    "stop": _stop, "estop": _estop, "reset": _reset, "home": _home, "tare": _tare,
    "load": _load, "confirm": _confirm, "pause": _pause, "collect": _collect,
    "reload": _reload,  # internal (SIGHUP): built by the daemon, not in VERBS
}

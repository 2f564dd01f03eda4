"""The motion commands, in the loop's thread: setpoint and profile (pressure or length
targets), mode (pressure, length_force, position) and model (a feedforward swap)."""

from __future__ import annotations

import dataclasses
import math

from pamd.loop.commands.guards import can_move, named_muscles, need_length_datum
from pamd.loop.commands.model_file import prepare_model
from pamd.loop.commands.prepared import PreparedModelArgs
from pamd.loop.commands.verb_registry import Verb
from pamd.loop.control.controller import RigController
from pamd.loop.control.length_control import MODE_NAMES
from pamd.loop.control.length_targets import length_profile
from pamd.loop.control.muscle import MuscleController
from pamd.loop.control.onoff import POSITION_TAKES_NO_MODEL
from pamd.loop.control.rig_safe_state import SAFE_SETPOINT_BAND_BAR
from pamd.profiles import Profile, ProfileSpec
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.tick import Mode, State
from pamd.wire.verbs.args import LENGTH_PROFILE_FIELDS, ModeArgs, ProfileArgs, SetpointArgs
from pamd.wire.verbs.table import VERBS as SPECS


def _start(ctrl: RigController, ms: list[MuscleController], spec_: ProfileSpec) -> float | None:
    for m in ms:
        spec_.check(0.0, m.envelope.max_pressure_bar, m.envelope.slew_limit_bar_per_s,
                    ctrl.cfg.period_s)
    total = None
    for m in ms:
        prof = Profile(spec_, ctrl.now, m.setpoint_bar, m.envelope.slew_limit_bar_per_s)
        m.start_profile(prof)
        total = prof.total_s()
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"{spec_.shape_name} profile started")
    return total


def _setpoint(ctrl: RigController, a: SetpointArgs) -> JsonObject:
    can_move(ctrl)
    ms = named_muscles(ctrl, a.muscle)
    need_length_datum(ms)
    m = ms[0]
    if m.in_length_mode or a.bar is None:
        out = _length_setpoint(ctrl, m, a)
        ctrl.arm_deadman(m, a.deadman_s)
        return dict(out, deadman_s=a.deadman_s)
    if a.length_mm is not None or a.force_n is not None:
        raise CommandRefused(f"{m.name} is in pressure mode: length_mm and force_n are "
                             "targets of the length_force and position modes (send mode "
                             "first); give bar alone")
    max_p, slew = m.envelope.max_pressure_bar, m.envelope.slew_limit_bar_per_s
    if not 0.0 <= a.bar <= max_p:
        raise CommandRefused(f"{m.name}: {a.bar:g} bar is outside 0-{max_p:g} bar")
    dist = abs(a.bar - m.setpoint_bar)
    rate = 0.5 * slew if not a.ramp_s else dist / a.ramp_s
    if rate > slew:
        raise CommandRefused(f"{m.name}: reaching {a.bar:g} bar in {a.ramp_s:g} s needs "
                             f"{rate:.3g} bar/s, above the slew limit {slew:g} bar/s")
    spec_ = ProfileSpec(shape_name="ramp", to_bar=a.bar, rate_bar_per_s=max(rate, 1e-6),
                        lead_in_bar_per_s=slew)
    m.start_profile(Profile(spec_, ctrl.now, m.setpoint_bar, slew))
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"setpoint {m.name} {a.bar:g} bar")
    ctrl.arm_deadman(m, a.deadman_s)  # streamed setpoints: each one re-arms (or disarms)
    return {"muscle": m.name, "bar": a.bar, "ramp_s": dist / rate if rate > 0 else 0.0,
            "deadman_s": a.deadman_s}


def _profile(ctrl: RigController, a: ProfileArgs) -> JsonObject:
    can_move(ctrl)
    ms = named_muscles(ctrl, a.muscle)
    need_length_datum(ms)
    if any(m.in_length_mode for m in ms) or any(
            getattr(a, k) is not None for k in LENGTH_PROFILE_FIELDS):
        return _length_profile(ctrl, ms, a)
    fields = dataclasses.asdict(a)
    fields.pop("muscle")
    fields["shape_name"] = fields.pop("shape")
    for k in LENGTH_PROFILE_FIELDS:
        fields.pop(k)
    total = _start(ctrl, ms, ProfileSpec(**fields))
    return {"duration_s": total}


def _length_setpoint(ctrl: RigController, m: MuscleController, a: SetpointArgs) -> JsonObject:
    """A length (and force) target in the length modes, reached by a ramp."""

    mode = m.mode.name.lower()
    if not m.in_length_mode:
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
    env = m.envelope
    rated = env.rating.theoretical_force_n
    if a.force_n is not None and a.force_n > rated:
        raise CommandRefused(f"{m.name}: {a.force_n:g} N exceeds the {env.muscle_type}'s "
                             f"theoretical force ({rated:g} N)")
    out: JsonObject = {"muscle": m.name, "mode": mode}
    prof = None
    if a.length_mm is not None:
        l0 = env.nominal_length_mm
        x = (l0 - a.length_mm) / l0
        max_rate = env.max_length_rate_per_s
        dist = abs(x - (l0 - m.target_length_mm) / l0)
        rate = 0.5 * max_rate if not a.ramp_s else dist / a.ramp_s
        if rate > max_rate:
            raise CommandRefused(
                f"{m.name}: reaching {a.length_mm:g} mm in {a.ramp_s:g} s needs "
                f"{rate * l0:.3g} mm/s, above the length rate limit {max_rate * l0:.3g} mm/s "
                f"({env.length_rate_origin})")
        prof = length_profile(env, m.load_kg, m.target_length_mm, ctrl.now, "ramp",
                              min_contraction=None, max_contraction=None,
                              to_contraction=x, freq_hz=1.0, cycles=None,
                              rate_per_s=max(rate, 1e-6), rise_s=None, duration_s=None,
                              lead_in_per_s=max_rate)
        out.update(length_mm=a.length_mm, ramp_s=dist / rate if rate > 0 else 0.0)
    if a.force_n is not None:
        out["force_n"] = a.force_n
    m.set_length_targets(prof, a.force_n)
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"setpoint {m.name} " + ", ".join(
        f"{k} {v:g}" for k, v in out.items() if k in ("length_mm", "force_n")))
    return out


def _length_profile(ctrl: RigController, ms: list[MuscleController],
                    a: ProfileArgs) -> JsonObject:
    """A length profile (contraction units) on muscles in a length mode."""

    for m in ms:
        if not m.in_length_mode:
            raise CommandRefused(f"{m.name} is in pressure mode: a length profile "
                                 "(min/max/to_contraction) needs mode length_force or position "
                                 "first")
    profiles = [length_profile(m.envelope, m.load_kg, m.target_length_mm, ctrl.now, a.shape,
                               min_contraction=a.min_contraction,
                               max_contraction=a.max_contraction,
                               to_contraction=a.to_contraction, freq_hz=a.freq_hz,
                               cycles=a.cycles, rate_per_s=a.rate_per_s, rise_s=a.rise_s,
                               duration_s=a.duration_s, lead_in_per_s=a.lead_in_per_s,
                               period_s=ctrl.cfg.period_s)
                for m in ms]  # every muscle checked before any moves
    total = None
    for m, prof in zip(ms, profiles, strict=True):
        m.start_length_profile(prof)
        total = prof.total_s()
    ctrl.supervisor.go(ctrl.now, State.RUNNING, f"{a.shape} length profile started")
    return {"duration_s": total, "length_profile": True}


def _mode(ctrl: RigController, a: ModeArgs) -> JsonObject:

    can_move(ctrl)
    if a.mode not in MODE_NAMES:
        raise CommandRefused(f"unknown mode {a.mode!r}; use {', '.join(MODE_NAMES)}")
    seq = ctrl.plan_run
    if seq is not None and not seq.outcome:
        raise CommandRefused("an experiment plan is running; its profiles are pressure "
                             "profiles (pause or stop it first)")
    ms = named_muscles(ctrl, a.muscle)
    mode = MODE_NAMES[a.mode]
    if mode == Mode.PRESSURE:
        for m in ms:
            if m.in_length_mode:
                m.leave_length_mode()
        return {"mode": a.mode, "muscles": [m.name for m in ms]}
    if a.ilc and mode != Mode.POSITION:
        raise CommandRefused("ilc: iterative learning runs in position mode only")
    if not a.feedforward and mode != Mode.POSITION:
        raise CommandRefused("length_force mode is the model itself: feedforward cannot be "
                             "off")
    need_length_datum(ms)
    for m in ms:
        _can_enter(m, mode, a)
    for m in ms:
        m.enter_mode(mode, a.feedforward, a.ilc)
    return {"mode": a.mode, "muscles": [m.name for m in ms],
            "feedforward_bar": {m.name: m.feedforward_bar for m in ms}}


def _can_enter(m: MuscleController, mode: Mode, a: ModeArgs) -> None:
    """Refuses, saying why, a length mode muscle `m` cannot enter now: still ramping to
    its safe pressure, an on/off muscle's position mode with a model, no model for a
    mode with feedforward, no length or force reading to start from."""
    if m.in_safe_ramp and abs(m.setpoint_bar - m.safe_pressure_bar) > \
            SAFE_SETPOINT_BAND_BAR:  # still ramping: it would drop a length mode
        raise CommandRefused(
            f"{m.name} is ramping to its safe pressure ({m.safe_pressure_bar:.2f} bar: a "
            "stop, a deadman or a start-up outside the limits); send a setpoint or a "
            f"pressure profile to take over from the ramp, then mode {a.mode}")
    if mode == Mode.POSITION and a.feedforward and m.onoff:
        raise CommandRefused(f"{m.name}: position mode with feedforward: "
                             f"{POSITION_TAKES_NO_MODEL}")
    if a.feedforward and not m.has_model:
        raise CommandRefused(
            f"{m.name}: no model for {a.mode} mode; name model_file in the config, `pamd "
            "run --model FILE` or send the model command first (position mode with "
            "feedforward false runs the position PID alone)")
    if not (math.isfinite(m.length_mm) and math.isfinite(m.force_n)):
        raise CommandRefused(f"{m.name}: no length/force reading to start from")


def _model(ctrl: RigController, a: object) -> JsonObject:
    """Swap in a model compiled outside the loop (`prepare_command`)."""
    if not isinstance(a, PreparedModelArgs):
        raise CommandRefused("model: the file was not loaded (send the command through the "
                             "daemon, which reads and checks it outside the loop)")
    m = named_muscles(ctrl, a.muscle)[0]
    diff = m.swap_model(a.feedforward)
    return {**a.describe(), "mode": m.mode.name.lower(), "taken_up_bar": diff}


VERBS: tuple[Verb, ...] = (
    Verb(SPECS["setpoint"], _setpoint),
    Verb(SPECS["profile"], _profile),
    Verb(SPECS["mode"], _mode),
    Verb(SPECS["model"], _model, prepare=prepare_model),
)

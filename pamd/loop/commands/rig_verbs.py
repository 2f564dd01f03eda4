"""The rig's state and settings commands, in the loop's thread: hold, resume, stop,
estop and reset; home, tare and load (calibration and load); reload (SIGHUP)."""

from __future__ import annotations

import math
import time

from pamd.drivers.safe_outputs import push_safe_outputs
from pamd.loop.commands.guards import can_move, idle_or_hold, named_muscles
from pamd.loop.commands.prepared import ReloadArgs
from pamd.loop.commands.verb_registry import Verb
from pamd.loop.control.controller import RigController
from pamd.loop.experiment.sequencer import running_plan
from pamd.loop.safety.datums import check_home, tare_offset
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.tick import State
from pamd.wire.verbs.args import EstopArgs, HomeArgs, LoadArgs, NoArgs, TareArgs
from pamd.wire.verbs.table import VERBS as SPECS
from pamd.wire.verbs.table import VerbSpec


def _hold(ctrl: RigController, a: NoArgs) -> JsonObject:
    can_move(ctrl)
    ctrl.enter_hold(ctrl.now, "hold: setpoints frozen")
    return {}


def _resume(ctrl: RigController, a: NoArgs) -> JsonObject:
    if ctrl.supervisor.state != State.HOLD:
        raise CommandRefused(f"resume only from HOLD (state is {ctrl.supervisor.state.name})")
    paused = ctrl.now - ctrl.hold_started
    seq = running_plan(ctrl)
    running = seq is not None and not seq.outcome
    for m in ctrl.muscles:
        if m.resume(paused):
            running = True
    if seq is not None:
        seq.awaiting_operator = "" if seq.phase == "pause" else seq.awaiting_operator
    ctrl.supervisor.go(ctrl.now, State.RUNNING if running else State.IDLE, "resumed")
    return {}


def _stop(ctrl: RigController, a: NoArgs) -> JsonObject:
    if ctrl.supervisor.latched:
        raise CommandRefused(f"the rig is already in {ctrl.supervisor.state.name}, at its safe "
                             "state")
    ctrl.go_safe("stop: ramping to the safe state")
    return {}


def _estop(ctrl: RigController, a: EstopArgs) -> JsonObject:
    for m in ctrl.muscles:
        m.stop_profile()
    ctrl.supervisor.estop(ctrl.now, f"emergency stop: {a.reason}")
    return {}


def _reset(ctrl: RigController, a: NoArgs) -> JsonObject:
    refused = ctrl.reset_latched("command")  # the restart interlock included
    if refused is not None:
        raise CommandRefused(refused)
    return {}


def _home(ctrl: RigController, a: HomeArgs) -> JsonObject:
    idle_or_hold(ctrl, "home")
    m = named_muscles(ctrl, a.muscle)[0]
    raw_len = m.length_mm - m.datums.length_offset_mm
    if not math.isfinite(raw_len):
        raise CommandRefused(f"{m.name}: no length reading to set its datum from")
    check_home(m, a.length_mm)  # absolute sensor, untrusted, moving, or disagreeing: refused
    # At once in software; a device that takes the preset too confirms later.
    offset = m.home(a.length_mm, raw_len, time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    ctrl.mark_calibration_dirty()  # saved outside the loop's thread
    return {"muscle": m.name, "length_offset_mm": offset}


def _tare(ctrl: RigController, a: TareArgs) -> JsonObject:
    idle_or_hold(ctrl, "tare")
    ms = named_muscles(ctrl, a.muscle)
    offsets = [tare_offset(m, a.load_kg) for m in ms]  # all checked before any changes
    out = {}
    for m, offset in zip(ms, offsets, strict=True):
        m.tare(offset, time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        out[m.name] = offset
    ctrl.mark_calibration_dirty()  # saved outside the loop's thread
    return {"force_offset_n": out}


def _load(ctrl: RigController, a: LoadArgs) -> JsonObject:
    m = named_muscles(ctrl, a.muscle)[0]
    rated = m.envelope.rating.max_load_kg
    if a.load_kg > rated:
        raise CommandRefused(f"{m.name}: {a.load_kg:g} kg exceeds the "
                             f"{m.envelope.muscle_type} rating ({rated:g} kg)")
    m.set_load(a.load_kg)
    push_safe_outputs(ctrl)  # modules with a comm watchdog hold the new safe state
    return {"muscle": m.name, "load_kg": a.load_kg, "safe_pressure_bar": m.safe_pressure_bar}


def _reload(ctrl: RigController, a: ReloadArgs) -> JsonObject:
    """A reloaded config: gains and timeouts at once; limits, slew, loads and nominal
    lengths only at rest (`RigController.at_rest`: IDLE, nothing moving, a ramp to the
    safe state completed; otherwise reported as deferred: the daemon sends the command
    again at the next rest). Refused as a whole, changing nothing, if a held pressure
    is above a new pressure limit. What became of it (pending until the next rest,
    refused and why, applied) is the controller's `reload_note`, which status shows."""
    settings = a.plan
    if [s.muscle for s in settings] != [m.name for m in ctrl.muscles]:
        raise _refused(ctrl, a, "reload: the muscles differ from the running rig's; that "
                       "needs a restart")
    with_limits = bool(a.idle_only) and ctrl.at_rest()
    if with_limits:
        for m, s in zip(ctrl.muscles, settings, strict=True):
            if m.started and m.setpoint_bar > s.limits.max_pressure_bar:
                raise _refused(
                    ctrl, a, f"reload: {m.name} holds {m.setpoint_bar:.2f} bar, above the new "
                    f"pressure limit {s.limits.max_pressure_bar:g} bar; lower the setpoint "
                    "and send SIGHUP again (nothing changed)")
    for m, s in zip(ctrl.muscles, settings, strict=True):
        m.apply_settings(s, with_limits)
    ctrl.set_startup_timeout(a.startup_timeout_s)
    if with_limits:
        push_safe_outputs(ctrl)  # loads or limits may have moved the safe pressures
        # a new load_kg, checked against the force at rest (the rig is at rest)
        ctrl.confirm_loads([s.muscle for s in settings if s.load_kg is not None], "reload")
    deferred = [] if with_limits or not a.idle_only else list(a.idle_only)
    state = ctrl.supervisor.state.name
    if deferred:
        ctrl.reload_note = {"outcome": "pending", "keys": deferred, "t_s": ctrl.now,
                            "reason": f"the rig is not at rest ({ctrl.rest_text()}): "
                            "applied at the next rest"}
    else:
        ctrl.reload_note = {"outcome": "applied", "keys": list(a.at_once) + list(
            a.idle_only), "t_s": ctrl.now, "reason": ""}
    return {"applied": list(a.at_once) + (list(a.idle_only) if with_limits else []),
            "deferred": deferred, "state": state}


def _refused(ctrl: RigController, a: ReloadArgs, reason: str) -> CommandRefused:
    ctrl.reload_note = {"outcome": "refused", "keys": list(a.at_once) + list(a.idle_only),
                        "t_s": ctrl.now, "reason": reason}
    return CommandRefused(reason)


VERBS: tuple[Verb, ...] = (
    Verb(SPECS["hold"], _hold),
    Verb(SPECS["resume"], _resume),
    Verb(SPECS["stop"], _stop),
    Verb(SPECS["estop"], _estop),
    Verb(SPECS["reset"], _reset),
    Verb(SPECS["home"], _home),
    Verb(SPECS["tare"], _tare),
    Verb(SPECS["load"], _load),
    Verb(VerbSpec("reload", ReloadArgs, "a reloaded config (SIGHUP)", internal=True), _reload),
)

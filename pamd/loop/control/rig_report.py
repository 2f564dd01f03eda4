"""What the rig controller says (one job of `pamd.loop.control.controller`): its status, and the
events of its rare paths (a reading no longer trusted, a profile held at a soft
limit). Built from the muscles' read-only properties; nothing here changes the rig."""

from __future__ import annotations

from collections.abc import Sequence

from pamd.loop.control.muscle import MuscleController
from pamd.loop.safety import Supervisor
from pamd.loop.safety.chain import SafetyChain
from pamd.wire.declare.jsonsafe import JsonObject


def finding_event(m: MuscleController) -> JsonObject:
    """The `implausible` event of a reading that is no longer trusted (whatever the
    state: a fault already latched keeps its first reason; this one is still said).
    Takes the muscle's finding."""
    plaus = m.plausibility
    trusted = [n for n, ok in (("pressure", plaus.pressure_ok), ("force", plaus.force_ok),
                               ("length", plaus.length_ok)) if ok]
    return {"muscle": m.name, "reason": m.take_finding(), "trusted": trusted}


def soft_limit_event(m: MuscleController) -> JsonObject:
    """The `soft_limit` event of a profile held at a soft limit for more than 1 s.
    Takes the muscle's limit report."""
    limit = m.take_limit_report()
    setpoint, cmd = m.setpoint_bar, m.valve_cmd_bar
    return {"muscle": m.name, "limit": limit, "held_s": 1.0,
            "setpoint_bar": setpoint, "valve_cmd_bar": cmd,
            "reason": f"{m.name}: the profile is held at the {limit} limit (setpoint "
                      f"{setpoint:.2f} bar, command {cmd:.2f} bar) for more than 1 s"}


def feedforward_events(m: MuscleController) -> list[JsonObject]:
    """The `feedforward` events not yet said (`pamd.loop.control.off_data`): the model's
    inputs off its training domain (once since the mode or the model came), its
    feedforward oscillating against the pressure loop (once an episode). Takes them."""
    lc = m.length_control
    wd, ff = lc.watch, lc.ff
    out: list[JsonObject] = []
    if wd.pending_off and ff is not None:
        wd.pending_off = False
        names = ff.off_names(wd.mask)
        signals = dict(zip(("force_n", "length_mm", "contraction", "velocity_mm_s",
                            "pressure_bar"), wd.values, strict=True))
        values = {n: signals[n] for n in names}
        fades = wd.policy == "fade" and lc.position
        action = "fade" if fades else "warn"
        what = ", ".join(f"{n} {values[n]:.4g}" for n in names)
        then = (f"the feedforward fades to the position PID alone over {wd.fade_s:g} s "
                "while they are outside" if fades else "the feedforward goes on (off_data: "
                f"{wd.policy}{', length_force mode' if not lc.position else ''})")
        out.append({"muscle": m.name, "what": "off_data", "action": action,
                    "inputs": names, "values": values,
                    "reason": f"{m.name}: the model's inputs left its training domain "
                              f"({what}; the domain: {ff.domain.describe()}); {then}"})
    if wd.pending_osc:
        wd.pending_osc = False
        osc = wd.oscillation
        out.append({"muscle": m.name, "what": "oscillating", "action": "warn",
                    "inputs": ["force_n"], "values": {},
                    "amplitude_bar": round(osc.amplitude_bar, 4),
                    "reason": f"{m.name}: the feedforward oscillates against the pressure "
                              "loop (it turns round many times a second where the target "
                              "does not: its force input feeds the load's bounce back; a "
                              "model whose force slope is far steeper than the muscle's); "
                              "retrain it (pamd train's default rule ridge), or run the "
                              "position PID alone"})
    return out


def muscle_status(m: MuscleController) -> JsonObject:
    """One muscle's part of the rig's status."""
    return {
        "pressure_bar": m.pressure_bar, "setpoint_bar": m.setpoint_bar,
        "valve_cmd_bar": m.valve_cmd_bar, "force_n": m.force_n,
        "length_mm": m.length_mm, "contraction": m.contraction,
        "load_kg": m.load_kg, "safe_pressure_bar": m.safe_pressure_bar,
        "has_length_datum": m.has_length_datum, "mode": m.mode.name.lower(),
        "safe_ramp": m.in_safe_ramp,
        "trusted": {"pressure": m.plausibility.pressure_ok,
                    "force": m.plausibility.force_ok,
                    "length": m.plausibility.length_ok},
        "profile": m.profile.spec.shape_name if m.profile else None,
        "limits": {"max_pressure_bar": m.envelope.max_pressure_bar,
                   "max_contraction": m.envelope.max_contraction,
                   "max_pretension": m.envelope.max_pretension},
    }


def chain_status(chain: SafetyChain) -> JsonObject | None:
    """The safety chain's part of the rig's status (None: no chain configured; a
    signal not read yet, NaN, as None)."""
    if not chain.configured:
        return None
    return {
        "closed": None if chain.closed != chain.closed else bool(chain.closed),
        "supply_bar": None if chain.supply_bar != chain.supply_bar else chain.supply_bar,
        "supply_out": chain.supply_out,
        "reset_by": chain.reset_by,
    }


def rig_status(supervisor: Supervisor, chain: SafetyChain,
               muscles: Sequence[MuscleController],
               reload_note: JsonObject | None) -> JsonObject:
    """The rig controller's status: state, reasons, the last reload's note, the
    safety chain and every muscle."""
    return {
        "state": supervisor.state.name,
        "reason": supervisor.reason,
        "fault": supervisor.fault_reason,
        "reload": reload_note,
        "safety_chain": chain_status(chain),
        "muscles": {m.name: muscle_status(m) for m in muscles},
    }

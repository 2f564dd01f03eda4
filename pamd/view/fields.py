"""What each recorded field is: its unit, and the names behind the codes (supervisor
states, control modes, flag bits). One table for the Python API, the MATLAB and CSV
exports and the plots."""

from __future__ import annotations

from pamd.tick import LOOP_FIELDS, MUSCLE_FIELDS, Flag, Mode, State

#: fields whose unit is not in their name
_UNITS = {"tick": "tick", "contraction": "1", "state": "name", "mode": "name",
          "flags": "bits", "overruns": "periods", "lost_records": "records",
          "segment": "step + 1", "load_kg": "kg", "adapt_state": "code"}
_SUFFIXES = (("_mm_s", "mm/s"), ("_bar", "bar"), ("_n", "N"), ("_mm", "mm"), ("_s", "s"),
             ("_kg", "kg"))

#: every field of a muscle's table in the API and the exports, in order
MUSCLE_COLUMNS: tuple[str, ...] = ("tick", "t_s", *MUSCLE_FIELDS, "state", "segment")
LOOP_COLUMNS: tuple[str, ...] = LOOP_FIELDS

STATE_NAMES: dict[int, str] = {s.value: s.name for s in State}
MODE_NAMES: dict[int, str] = {m.value: m.name.lower() for m in Mode}
FLAG_BITS: dict[str, int] = {f.name: int(f.value) for f in Flag if f.name}
FLAG_MEANINGS: dict[str, str] = {
    "STALE": "a signal of this muscle is older than its timeout",
    "SOFT_LIMIT_PRESSURE": "command clamped at the pressure limit",
    "SOFT_LIMIT_CONTRACTION": "command reduced near the contraction limit",
    "PRETENSION_LIMIT": "stretched past the pretension limit: pressure raised",
    "SLEW_LIMITED": "setpoint rate limited",
    "OUTPUT_SATURATED": "PID output at its limit",
    "FF_CLIPPED": "feedforward inputs outside the model's trained range",
    "NOT_REFERENCED": "length not referenced (home)",
    "EXHAUST_OPEN": "exhaust valve open",
    "TRACKING": "pressure outside the tracking band (timer running)",
}
DESCRIPTIONS: dict[str, str] = {
    "tick": "tick number since the run start", "t_s": "loop time since the run start",
    "wake_latency_s": "how late the loop woke for this tick",
    "compute_s": "compute time of the previous tick",
    "overruns": "periods skipped since start (cumulative)", "state": "supervisor state",
    "lost_records": "records lost since start (cumulative)",
    "segment": "experiment step + 1 (0 outside a plan)",
    "pressure_bar": "measured pressure", "force_n": "measured force",
    "length_mm": "measured length", "contraction": "(nominal - length) / nominal",
    "velocity_mm_s": "filtered d(length)/dt", "setpoint_bar": "pressure reference",
    "feedforward_bar": "inverse-model (ANFIS) part of the setpoint",
    "pid_p_bar": "PID proportional term", "pid_i_bar": "PID integral term",
    "pid_d_bar": "PID derivative term", "valve_cmd_bar": "command written to the regulator",
    "target_length_mm": "length target (NaN outside length modes)",
    "target_force_n": "force target (NaN outside length_force mode)",
    "safe_pressure_bar": "safe pressure for the hanging load", "mode": "control mode",
    "flags": "condition bits (see the flag table)",
    "adapt_drift_bar": "adapted minus trained model output at the last adaptation sample",
    "adapt_state": "model adaptation: 0 off, 1 adapting, 2 paused, 3 frozen, 4 rate-limited",
}


def unit_of(name: str) -> str:
    """`pressure_bar` -> "bar", `contraction` -> "1" (a fraction), `state` -> "name"."""
    if name in _UNITS:
        return _UNITS[name]
    for suffix, unit in _SUFFIXES:
        if name.endswith(suffix):
            return unit
    return ""


def state_name(code: float) -> str:
    return STATE_NAMES.get(int(code), f"?{code:g}") if code == code else ""


def mode_name(code: float) -> str:
    return MODE_NAMES.get(int(code), f"?{code:g}") if code == code else ""


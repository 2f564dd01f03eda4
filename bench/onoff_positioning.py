"""Benchmark: on/off valves (config/sim-onoff.yaml) on the simulated rig; prints the
issue #14 figures and issue #29's plateaus. Virtual clock, deterministic.

0. Plateaus (issue 29, seed 004: Sarosi positions to 0.01 mm): from start-up (the
   muscle at 0 bar with its load hanging; at 80 kg, beyond the pretension limit, the
   start-up's safe ramp lifts it first and a pressure setpoint takes over from it),
   mode position and a length step profile, 3 cycles at 0.1 Hz (5 s plateaus, edges at
   the length-rate limit): 190 <-> 185 mm for 5 mm steps, 195 <-> 185 mm for 10 mm
   (190 <-> 180 asks more than 6 bar at 80 kg), at 15, 30, 50 and 80 kg. Per plateau,
   the first after start-up included: the settling time (from the plateau's start
   until the true length stays within 0.02 mm of the target) and the worst error in
   its last second (goal: within 0.02 mm).

1. Positioning (mode position, seed 004's sliding mode): a 10 mm length setpoint
   (shorter), sent as a 1 s ramp (10 mm/s, 0.05 contraction/s: the length rate limit
   of issue #14's time; the derived limit now allows 20 mm/s on this rig). Settling
   time: from the command until the true length stays within 0.02 mm of the target
   (goal: 2 s); then 4 s at rest: the worst error and each valve's switchings per
   second (goal: <= 5/s).
2. PWM pressure tracking of the spine's 0.05 Hz 0-6 bar sine, 3 cycles: RMSE of the
   measured pressure against the setpoint after the first cycle (goal: <= 0.1 bar),
   and each valve's switchings per second.

The gains are config/sim-onoff.yaml's, from the step test of bench/tune_onoff.py.

    python bench/onoff_positioning.py
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import _lockdir  # noqa: F401  (the run's own rig-lock directory)
import yaml

from pamd.config import load_config
from pamd.loop.harness import Harness
from pamd.wire.tick import State

REPO = Path(__file__).resolve().parents[1]
DT = 0.001
STEP_MM = 10.0
BAND_MM = 0.02
REST_S = 4.0


def onoff_harness(load_kg: float = 30.0, initial_bar: float = 0.0) -> Harness:
    d: dict[str, Any] = yaml.safe_load((REPO / "config" / "sim-onoff.yaml").read_text())
    d["loop"]["clock"] = "virtual"
    d["loop"]["realtime"] = {"enabled": False}
    d["telemetry"] = {"enabled": False}
    d["muscles"][0]["load_kg"] = load_kg
    sim = d["drivers"][0]["options"]["muscles"][0]
    sim["load_kg"] = load_kg
    sim["initial_pressure_bar"] = initial_bar
    path = Path(tempfile.mkdtemp()) / "sim-onoff.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    h = Harness(load_config(str(path)))
    h.step(0.01)
    return h


#: the setpoint ramp's rate (contraction/s): issue #14's figures were measured at it
RAMP_RATE_PER_S = 0.05


def positioning() -> dict[str, float]:
    """The 10 mm step: settling time (s), worst error at rest (mm), switchings/s at
    rest per valve."""
    h = onoff_harness(initial_bar=3.0)
    try:
        h.step(1.0)
        m, plant = h.m1, h.sim.plant("m1")
        assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
        target = plant.length_mm - STEP_MM
        fastest_mm_s = m.envelope.nominal_length_mm * RAMP_RATE_PER_S
        v = h.cmd("setpoint", muscle="m1", length_mm=target,
                  ramp_s=1.001 * STEP_MM / fastest_mm_s)
        assert v["ok"], v
        t0 = h.t
        errors: list[tuple[float, float]] = []
        for k in range(round((2.0 + REST_S) / DT)):
            if k == round(2.0 / DT):
                at_2s = m.actuation.switches()
            h.step(DT)
            errors.append((h.t - t0, abs(plant.length_mm - target)))
        end = m.actuation.switches()
        assert h.ctrl.supervisor.state == State.RUNNING, h.ctrl.supervisor.faults
    finally:
        h.rig.close()
    settle = 0.0
    for t, e in errors:
        if e > BAND_MM:
            settle = t
    rest = [e for t, e in errors if t > 2.0]
    return {"settle_s": settle, "rest_max_error_mm": max(rest),
            "rest_inflate_per_s": (end["inflate"] - at_2s["inflate"]) / REST_S,
            "rest_exhaust_per_s": (end["exhaust"] - at_2s["exhaust"]) / REST_S}


#: issue 29's loads (kg) and steps (mm: the plateaus' lengths, long then short)
LOADS_KG = (15.0, 30.0, 50.0, 80.0)
STEPS_MM = {5.0: (190.0, 185.0), 10.0: (195.0, 185.0)}
PLATEAU_FREQ_HZ = 0.1
PLATEAU_CYCLES = 3


def start_up(load_kg: float) -> Harness:
    """The rig just started with the muscle at 0 bar and the load hanging, settled (3 s);
    where that is outside the limits (the start-up's safe ramp holds it), a pressure
    setpoint at the measured pressure takes over, as an operator would."""
    h = onoff_harness(load_kg=load_kg, initial_bar=0.0)
    h.step(3.0)
    m = h.m1
    if m.in_safe_ramp:
        v = h.cmd("setpoint", muscle="m1", bar=round(m.pressure_bar, 3))
        assert v["ok"], v
        h.step(0.5)
    return h


def plateaus(load_kg: float, step_mm: float) -> list[dict[str, float]]:
    """Each plateau of the step profile: target (mm), settle_s, last_s_max_error_mm."""
    long_mm, short_mm = STEPS_MM[step_mm]
    h = start_up(load_kg)
    try:
        m, plant = h.m1, h.sim.plant("m1")
        assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
        l0 = m.envelope.nominal_length_mm
        v = h.cmd("profile", muscle="m1", shape="step", min_contraction=1.0 - long_mm / l0,
                  max_contraction=1.0 - short_mm / l0, freq_hz=PLATEAU_FREQ_HZ,
                  cycles=PLATEAU_CYCLES)
        assert v["ok"], v
        end = h.t + float(v["duration_s"]) + 0.5 / PLATEAU_FREQ_HZ
        trace: list[tuple[float, float, float]] = []
        while h.t < end:
            h.step(DT)
            trace.append((h.t, m.target_length_mm, plant.length_mm))
        sup = h.ctrl.supervisor
        assert sup.state in (State.RUNNING, State.IDLE) and not sup.faults, sup.faults
    finally:
        h.rig.close()
    return plateau_figures(trace)


def plateau_figures(trace: list[tuple[float, float, float]]) -> list[dict[str, float]]:
    """Each plateau of a (t_s, target_mm, length_mm) trace, a target held 1 s or more:
    target (mm), settle_s (the last time the length was outside BAND_MM of it, from the
    plateau's start) and last_s_max_error_mm (the worst error in its last second)."""
    out: list[dict[str, float]] = []
    start = 0
    for i in range(1, len(trace) + 1):
        if i < len(trace) and trace[i][1] == trace[start][1]:
            continue
        seg = trace[start:i]
        start = i
        if seg[-1][0] - seg[0][0] < 1.0:  # an edge
            continue
        target = seg[0][1]
        settle = 0.0
        for t, _, length in seg:
            if abs(length - target) > BAND_MM:
                settle = t - seg[0][0]
        last = max(abs(length - target) for t, _, length in seg if t > seg[-1][0] - 1.0)
        out.append({"target_mm": target, "settle_s": settle, "last_s_max_error_mm": last})
    return out


def print_plateaus(loads: tuple[float, ...] = LOADS_KG) -> bool:
    """Prints the plateau table; True if every plateau settles within BAND_MM."""
    ok = True
    print(f"Plateaus from start-up (step profile, {PLATEAU_CYCLES} cycles at "
          f"{PLATEAU_FREQ_HZ:g} Hz): settling time into {BAND_MM} mm / worst error in "
          "the plateau's last second; the first after start-up first")
    for load in loads:
        for step, (long_mm, short_mm) in STEPS_MM.items():
            ps = plateaus(load, step)
            cells = "  ".join(f"{p['target_mm']:.0f}: {p['settle_s']:.2f} s / "
                              f"{p['last_s_max_error_mm']:.3f}" for p in ps)
            worst = max(p["last_s_max_error_mm"] for p in ps)
            ok = ok and worst <= BAND_MM
            print(f"  {load:3g} kg, {step:g} mm ({long_mm:g} <-> {short_mm:g}): {cells}  "
                  f"[worst {worst:.3f} mm, slowest {max(p['settle_s'] for p in ps):.2f} s]")
    return ok


def sine_tracking(cycles: int = 3) -> dict[str, float]:
    """PWM tracking of the 0.05 Hz 0-6 bar sine at 30 kg, after the first cycle."""
    h = onoff_harness()
    try:
        assert h.cmd("profile", muscle="m1", shape="sine", min_bar=0.0, max_bar=6.0,
                     freq_hz=0.05, cycles=cycles)["ok"]
        m = h.m1
        first_end = h.t + m.profile.lead_in_s + 20.0
        sq, n = 0.0, 0
        sw0: dict[str, int] | None = None
        while h.ctrl.supervisor.state == State.RUNNING:
            h.step(DT)
            if h.t > first_end and h.ctrl.supervisor.state == State.RUNNING:
                if sw0 is None:
                    sw0, t_sw = m.actuation.switches(), h.t
                e = m.setpoint_bar - m.pressure_bar
                sq += e * e
                n += 1
        sw = m.actuation.switches()
        assert sw0 is not None and not h.ctrl.supervisor.faults, h.ctrl.supervisor.faults
        span = h.t - t_sw
    finally:
        h.rig.close()
    return {"rmse_bar": math.sqrt(sq / n),
            "inflate_per_s": (sw["inflate"] - sw0["inflate"]) / span,
            "exhaust_per_s": (sw["exhaust"] - sw0["exhaust"]) / span}


def main() -> None:
    print_plateaus()
    p = positioning()
    print(f"10 mm length step at 30 kg (sliding mode, 1 s ramp at the length rate limit): "
          f"within {BAND_MM} mm after {p['settle_s']:.3f} s (goal 2 s); at rest "
          f"({REST_S:g} s): worst error {p['rest_max_error_mm']:.3f} mm, switchings "
          f"{p['rest_inflate_per_s']:.2f}/s inflate, {p['rest_exhaust_per_s']:.2f}/s "
          "exhaust (goal <= 5/s per valve)")
    s = sine_tracking()
    print(f"PWM pressure tracking, 0.05 Hz 0-6 bar sine at 30 kg, after the first cycle: "
          f"RMSE {s['rmse_bar']:.4f} bar (goal <= 0.1 bar); switchings "
          f"{s['inflate_per_s']:.1f}/s inflate, {s['exhaust_per_s']:.1f}/s exhaust")


if __name__ == "__main__":
    main()

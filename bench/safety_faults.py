"""What each scripted fault does to the simulated rig with 80 kg hanging (issue 11).

For every failure of the sim driver's `faults` option, the rig runs a pressure
sine (2-5 bar, 0.25 Hz) on the virtual clock; the fault strikes at 1.0 s (and, in a
second table, 0.1 s into a stop's safe ramp from 4.5 bar). Printed per fault: when
it was detected (the first `implausible` event or fault, after the fault struck),
what named it, the valve command when the safe state began (a command below the
safe pressure then only rises), the lowest command in the safe state once it had
reached the safe pressure, the safe pressure, the largest command step in one tick
from the safe state's entry on (the tick that found the fault included; the slew
limit allows 0.005 bar at 5 bar/s and 1 kHz), and the lowest true contraction
after the fault (the pretension limit is -4 %).

    python bench/safety_faults.py [--load-kg 80] [--after-s 4]

Deterministic (virtual clock, fixed seed): the figures are the same on every run.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from _common import sim_config

from pamd.loop.harness import Harness
from pamd.wire.tick import State

FAULTS = [(s, k) for s in ("length", "force", "pressure")
          for k in ("dead", "stuck", "noisy", "jump", "silent")]
FAULTS += [("supply", "lost"), ("valve", "stuck"), ("driver", "error")]


def run_one(load_kg: float, signal: str, failure: str, scenario: str,
            after_s: float) -> dict[str, Any]:
    at_s = 1.0 if scenario == "running" else 2.1
    fault = {"at_s": at_s, "muscle": "*" if signal == "driver" else "m1", "signal": signal,
             "failure": failure}
    initial = 3.0
    cfg = sim_config(load_kg=load_kg, telemetry={"enabled": False}, drivers=[{
        "name": "sim", "type": "sim", "options": {"seed": 1, "faults": [fault], "muscles": [
            {"name": "m1", "load_kg": load_kg, "initial_pressure_bar": initial}]}}])
    h = Harness(cfg)
    try:
        m, plant, ctrl = h.m1, h.sim.plant("m1"), h.ctrl
        h.step(0.01)
        if scenario == "running":
            v = h.cmd("profile", shape="sine", min_bar=2.0, max_bar=5.0, freq_hz=0.25)
            assert v["ok"], v
        else:
            assert h.cmd("setpoint", muscle="m1", bar=4.5)["ok"]
        min_cmd = math.inf  # lowest command in a safe state, after it reached the safe pressure
        entry_cmd = math.nan  # the command at the first tick of the safe state
        reached = False
        min_x = math.inf
        max_step = 0.0  # the largest |command step| from the safe state's entry on
        prev_cmd = math.nan
        t_end = at_s + after_s
        stopped = False
        while h.t < t_end:
            if scenario == "safe_ramp" and not stopped and h.t >= 2.0:
                assert h.cmd("stop")["ok"]
                stopped = True
            before = m.valve_cmd_bar
            h.step(h.period_s)
            if h.t >= at_s:
                min_x = min(min_x, plant.contraction)
            safe = ctrl.supervisor.state in (State.FAULT, State.ESTOP) or m.in_safe_ramp
            if safe and m.started and h.t >= at_s:
                if entry_cmd != entry_cmd:
                    entry_cmd = before  # the command written before the entry tick
                    prev_cmd = before
                max_step = max(max_step, abs(m.valve_cmd_bar - prev_cmd))
                prev_cmd = m.valve_cmd_bar
                reached = reached or m.valve_cmd_bar >= m.safe_pressure_bar - 1e-9
                if reached:
                    min_cmd = min(min_cmd, m.valve_cmd_bar)
        detected = None
        named = ""
        for t, name, data in h.sink.events:
            if t < at_s - 1e-9:
                continue
            if name == "implausible" or (name == "transition" and data["to"] == "FAULT"):
                detected = t - at_s
                named = data.get("reason", "")
                break
        return {"detected_s": detected, "named": named, "min_cmd": min_cmd, "entry": entry_cmd,
                "max_step": max_step,
                "safe_bar": m.safe_pressure_bar, "min_x": min_x, "state": h.state}
    finally:
        h.rig.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--load-kg", type=float, default=80.0)
    ap.add_argument("--after-s", type=float, default=4.0, help="run time after the fault")
    args = ap.parse_args()
    for scenario, title in (("running", "fault at 1.0 s while RUNNING a 2-5 bar sine"),
                            ("safe_ramp", "fault 0.1 s into a stop's safe ramp from 4.5 bar")):
        print(f"\n{args.load_kg:g} kg, {title} (virtual clock, seed 1)")
        print(f"{'fault':<16} {'detected':>9} {'entry':>6} {'min cmd':>8} {'safe':>6} "
              f"{'step':>6} {'min x':>7}  state  named")
        for signal, failure in FAULTS:
            r = run_one(args.load_kg, signal, failure, scenario, args.after_s)
            det = ("not" if r["detected_s"] is None
                   else f"{max(0.0, 1000 * r['detected_s']):.0f} ms")
            cmd = "-" if r["min_cmd"] == math.inf else f"{r['min_cmd']:.3f}"
            named = r["named"].split(": ", 1)[-1][:70]
            entry = "-" if r["entry"] != r["entry"] else f"{r['entry']:.3f}"
            what = f"{signal} {failure}"
            print(f"{what:<16} {det:>9} {entry:>6} {cmd:>8} {r['safe_bar']:>6.3f} "
                  f"{r['max_step']:>6.3f} {100 * r['min_x']:>6.2f}%  {r['state']:<6} {named}")


if __name__ == "__main__":
    main()

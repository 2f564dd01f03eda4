"""Pressure tracking of a 0-6 bar sine (default the seeds' 0.05 Hz; `--freq HZ`) with a
30 kg load, after the first cycle (the plant issue's goal at 0.05 Hz: RMSE <= 0.01 bar
on the flow plant; issue 16's at 1 Hz: <= 0.05 bar), on the simulated rig of
config/sim.yaml (air that flows, sensors on a 1 kHz card, its shipped gains), beside:
  * the open-loop baseline (setpoint passed straight to the regulator: no PID, no
    rate feedforward), and
  * the old simple plant ('lag' pneumatics: a 10 ms dead time and a 30 ms lag on the
    setpoint, every sensor read in the tick it moves) with the gains it shipped with
    (kp 0.3, ki 20 1/s, rate feedforward 0.035 s).

A sine faster than the slew limit allows (`control.slew_limit_bar_per_s`, 5 bar/s by
default; a 0-6 bar sine at f Hz changes at up to 2 pi 3 f bar/s: 18.8 bar/s at 1 Hz) is
refused: this bench raises the limit to 1.1 x the sine's peak rate, as a user must in
their config to run it.

At 1 Hz the simulated regulator cannot vent the muscle as fast as the sine falls
below about 1.5 bar: its command sits at 0 bar for a fifth of each cycle while the
pressure lags up to 0.8 bar (air flows out ever slower as the pressure nears the
atmosphere's). `--min-bar 1.5` runs the range it can follow. The setpoint is not
previewed by the loop's dead time: the rate feedforward (dead time + lag) already is
that preview to first order, and the exact one (the profile sampled a dead time
ahead, plus the lag times its rate there) measured 0.0203 vs 0.0197 bar at 1 Hz
1.5-6 bar and 0.0161 vs 0.0161 bar at 0.5 Hz 0-6 bar: no better.

`--exhaust-assist-below BAR` adds the shipped gains with the exhaust valve assisting below
BAR (`muscles[].exhaust_assist_below_bar`); `--choose-assist` picks BAR from a grid on a
validation sine (0.8 Hz, never the test frequency) and then runs the test once.
Virtual clock, 3 cycles, deterministic.

Usage: python bench/tracking_sine.py [--freq 0.05] [--min-bar 0] [--cycles 3]
       [--exhaust-assist-below BAR | --choose-assist]"""

from __future__ import annotations

import argparse
import math
from typing import Any

import yaml
from _common import REPO, sim_config

from pamd.loop.commands import apply_command, parse_command
from pamd.loop.harness import Harness
from pamd.wire.tick import State

OPEN_LOOP = {"pid": {"kp": 0.0, "ki_per_s": 0.0, "kd_s": 0.0}, "rate_feedforward_s": 0.0}
OLD_GAINS = {"pid": {"kp": 0.3, "ki_per_s": 20.0, "kd_s": 0.0}, "rate_feedforward_s": 0.035}
OLD_PLANT = {"pneumatics": "lag", "pressure_sample_period_s": 0.0,
             "force_sample_period_s": 0.0, "length_sample_period_s": 0.0}


def plant_drivers(**muscle: Any) -> list[dict[str, Any]]:
    """The sim driver of config/sim.yaml with the muscle's options changed."""
    return [{"name": "sim", "type": "sim", "options": {"seed": 1, "muscles": [
        {"name": "m1", "nominal_length_mm": 200, "load_kg": 30, **muscle}]}}]


def slew_for(freq_hz: float, min_bar: float = 0.0) -> float:
    """The slew limit a min_bar-6 bar sine at `freq_hz` needs (1.1 x its peak rate; at
    least the default 5 bar/s), bar/s."""
    return max(5.0, 1.1 * 2.0 * math.pi * (6.0 - min_bar) / 2.0 * freq_hz)


def run(changes: dict[str, Any], cycles: int = 3, freq_hz: float = 0.05,
        min_bar: float = 0.0) -> tuple[float, float, float]:
    """RMSE (vs measured and vs true pressure) and max |error| after the first cycle, bar."""
    control = {"slew_limit_bar_per_s": slew_for(freq_hz, min_bar),
               **changes.get("control", {})}
    h = Harness(sim_config("virtual", **{**changes, "control": control}))
    h.step(0.01)
    apply_command(h.ctrl, parse_command("profile", {"shape": "sine", "cycles": cycles,
                                                    "freq_hz": freq_hz, "min_bar": min_bar}))
    t_first_cycle_end = h.t + h.m1.profile.lead_in_s + 1.0 / freq_hz
    sq = n = 0
    sq_true = 0.0
    worst = 0.0
    plant = h.sim.plant("m1")
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(0.001)
        if h.t > t_first_cycle_end and h.ctrl.supervisor.state == State.RUNNING:
            e = h.m1.setpoint_bar - h.m1.pressure_bar
            sq += e * e
            sq_true += (h.m1.setpoint_bar - plant.pressure_bar) ** 2
            n += 1
            worst = max(worst, abs(e))
    h.rig.close()
    return math.sqrt(sq / n), worst, math.sqrt(sq_true / n)


#: the validation sine's frequency and the grid the exhaust assist is chosen from
VALIDATION_HZ = 0.8
ASSIST_GRID_BAR = (0.5, 1.0, 1.5, 2.0, 3.0)


def assisted(below_bar: float) -> dict[str, Any]:
    """Config changes: config/sim.yaml's muscle with its exhaust valve assisting below
    `below_bar`."""
    muscles = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())["muscles"]
    muscles[0]["exhaust_assist_below_bar"] = below_bar
    return {"muscles": muscles}


def choose_assist(cycles: int, min_bar: float) -> float:
    """The assist threshold with the least RMSE on the validation sine."""
    print(f"  validation ({VALIDATION_HZ:g} Hz): exhaust assist below ... bar -> RMSE")
    best, best_rmse = ASSIST_GRID_BAR[0], math.inf
    for below in ASSIST_GRID_BAR:
        rmse = run(assisted(below), cycles, VALIDATION_HZ, min_bar)[0]
        print(f"    {below:g} bar: {rmse:.4f} bar")
        if rmse < best_rmse:
            best, best_rmse = below, rmse
    print(f"  chosen: {best:g} bar")
    return best


CASES: dict[str, dict[str, Any]] = {
    "flow plant, shipped gains": {},
    "flow plant, open loop": {"control": OPEN_LOOP},
    "old lag plant, its gains": {"control": OLD_GAINS, "drivers": plant_drivers(**OLD_PLANT)},
    "old lag plant, open loop": {"control": OPEN_LOOP, "drivers": plant_drivers(**OLD_PLANT)},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--freq", type=float, default=0.05, help="sine frequency, Hz")
    ap.add_argument("--cycles", type=int, default=3)
    ap.add_argument("--min-bar", type=float, default=0.0, help="the sine's low end (default "
                    "0; the high end is 6 bar)")
    ap.add_argument("--exhaust-assist-below", type=float, metavar="BAR",
                    help="also with the exhaust valve assisting below BAR")
    ap.add_argument("--choose-assist", action="store_true", help="choose BAR on the "
                    f"validation sine ({VALIDATION_HZ:g} Hz), then run the test with it")
    args = ap.parse_args()
    cases = dict(CASES)
    below = args.exhaust_assist_below
    if args.choose_assist:
        below = choose_assist(args.cycles, args.min_bar)
    if below is not None:
        cases[f"flow plant, shipped gains, exhaust assist below {below:g} bar"] = assisted(below)
    print(f"{args.freq:g} Hz {args.min_bar:g}-6 bar sine, 30 kg, cycles 2-{args.cycles} (after "
          f"the first; slew limit {slew_for(args.freq, args.min_bar):.1f} bar/s):")
    for name, changes in cases.items():
        rmse, worst, true_rmse = run(changes, args.cycles, args.freq, args.min_bar)
        print(f"  {name:27s} RMSE {rmse:.4f} bar (vs measured), {true_rmse:.4f} bar (vs true "
              f"pressure), max error {worst:.4f} bar")
    print("  goals: closed-loop RMSE <= 0.01 bar on the flow plant at 0.05 Hz, <= 0.05 bar at "
          "1 Hz; the pressure sensor's own noise is 0.003 bar")


if __name__ == "__main__":
    main()

"""Tune the pressure loop and the position loop from measured step responses.

What a lab does on its own rig, and how the shipped gains in config/sim.yaml (and
the schema's defaults) were found on the simulated one: never from the simulator's
parameters, only from what the sensors saw.

1. **Pressure loop** (regulator setpoint -> measured pressure). With the PID and the
   rate feedforward off and a fast slew limit (an *identification run*: only the
   regulator's own loop acts), small steps of the regulator setpoint (+-0.2 bar, the
   loop's working range, not the saturated fill of a large step) at 1.5, 3 and
   4.5 bar, up and down. Each response is fitted with a first-order-plus-dead-time
   model (`pamd.loop.control.tuning.fit_step`); the design model is their mean. Gains:
   Skogestad's SIMC PI (tau_c = theta) and `rate_feedforward_s` = theta + tau.
2. **Position loop** (pressure setpoint -> measured length), with the pressure loop
   closed on the gains of 1: +-0.5 bar steps of the pressure setpoint at 2.5 and
   3.5 bar, the length fitted the same way (its gain in mm/bar is negative: more
   pressure, shorter). Gains: SIMC PI on |K| (tau_c = theta), no derivative.

On the simulated rig (default) the steps run on the virtual clock through the
Harness. On real hardware, record the same steps and fit them:

    pamd run --config ident.yaml --record runs/ident      # PID 0, rate feedforward 0,
    pamd cmd setpoint --muscle m1 --bar 3.2 --ramp-s 0.002   # slew limit 500 bar/s; ...
    python bench/tune_pressure_loop.py --recording runs/ident/<file>.mcap

`--recording` finds the steps in the recorded valve command (pressure loop) or
setpoint (position loop, `--loop position`) and fits those.

    python bench/tune_pressure_loop.py [--config config/sim.yaml] [--load-kg 30]
"""

from __future__ import annotations

import os

import _lockdir  # noqa: F401  (the run's own rig-lock directory)

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import tempfile  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
import yaml  # noqa: E402

from pamd.client.tune.ident_run import IDENT_SLEW_BAR_PER_S  # noqa: E402
from pamd.client.tune.step_responses import StepResponse, fit_all, mean_model, steps_in  # noqa: E402
from pamd.client.tune.step_responses import position_gains as pkg_position_gains  # noqa: E402
from pamd.client.tune.step_responses import pressure_gains as pkg_pressure_gains  # noqa: E402
from pamd.client.tune.tune_report import print_fits  # noqa: E402
from pamd.config import LoadedConfig, load_config  # noqa: E402
from pamd.loop.control.tuning import Fopdt  # noqa: E402
from pamd.loop.harness import Harness  # noqa: E402

REPO = Path(__file__).resolve().parents[1]

EDGE_S = 0.002
PRESSURE_LEVELS_BAR = (1.5, 3.0, 4.5)
PRESSURE_STEP_BAR = 0.2
PRESSURE_RECORD_S = 0.4
POSITION_LEVELS_BAR = (2.5, 3.5)
POSITION_STEP_BAR = 0.5
POSITION_RECORD_S = 1.5
SETTLE_S = 2.0


def ident_config(path: str, load_kg: float | None, control: dict[str, Any]) -> LoadedConfig:
    """The config at `path` with `control` merged in (and the load, if given), for an
    identification run on the virtual clock."""
    data = yaml.safe_load(Path(path).read_text())
    data["loop"] = dict(data.get("loop") or {}, clock="virtual", realtime={"enabled": False})
    if load_kg is not None:
        for drv in data["drivers"]:
            if drv["type"] == "sim":
                for m in drv.setdefault("options", {}).setdefault("muscles", [{}]):
                    m["load_kg"] = load_kg
        for m in data["muscles"]:
            m["load_kg"] = load_kg
    merged = copy.deepcopy(data.get("control") or {})
    for key, value in control.items():
        if isinstance(value, dict):
            merged[key] = dict(merged.get(key) or {}, **value)
        else:
            merged[key] = value
    data["control"] = merged
    out = Path(tempfile.mkdtemp(prefix="pamd-tune-")) / Path(path).name
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return load_config(str(out))


def _record_steps(h: Harness, levels: tuple[float, ...], step_bar: float, record_s: float,
                  signal: str) -> list[StepResponse]:
    """From each level (reached slowly and settled), a step up by `step_bar` and back
    down, each recorded for `record_s`: `signal` is the muscle attribute recorded."""
    m = h.m1
    steps: list[StepResponse] = []
    pre_s = 0.05
    for level in levels:
        for target, label in ((level, None), (level + step_bar, "up"), (level, "down")):
            if label is None:
                assert h.cmd("setpoint", muscle=m.name, bar=target)["ok"]
                slew = m.envelope.slew_limit_bar_per_s
                h.step(SETTLE_S + abs(target - m.setpoint_bar) / (0.5 * slew))
                continue
            ts: list[float] = []
            ys: list[float] = []
            for _ in range(round(pre_s / h.period_s)):
                h.step(h.period_s)
                ts.append(h.t)
                ys.append(getattr(m, signal))
            t_cmd = h.t
            v = h.cmd("setpoint", muscle=m.name, bar=target, ramp_s=EDGE_S)
            assert v["ok"], v
            for _ in range(round(record_s / h.period_s)):
                h.step(h.period_s)
                ts.append(h.t)
                ys.append(getattr(m, signal))
            h.step(SETTLE_S)
            # the command moves at the first tick after it was taken, over one edge
            t_step = t_cmd + 0.5 * EDGE_S
            amp = step_bar if label == "up" else -step_bar
            steps.append(StepResponse(f"{level:.1f} bar {label}", t_step, amp, np.array(ts),
                              np.array(ys)))
    return steps


@dataclass(frozen=True)
class Tuning:
    pressure_model: Fopdt
    position_model: Fopdt
    kp: float
    ki_per_s: float
    rate_feedforward_s: float
    kp_bar_per_mm: float
    ki_bar_per_mm_s: float


def pressure_gains(model: Fopdt) -> tuple[float, float, float]:
    g = pkg_pressure_gains(model)
    return g.kp, g.ki_per_s, g.rate_feedforward_s


def position_gains(model: Fopdt) -> tuple[float, float]:
    g = pkg_position_gains(model)
    return g.kp_bar_per_mm, g.ki_bar_per_mm_s


def tune(config: str, load_kg: float | None, verbose: bool = True) -> Tuning:
    """Both identification runs on the simulated rig; the models and the gains."""
    open_loop = {"pid": {"kp": 0.0, "ki_per_s": 0.0, "kd_s": 0.0},
                 "rate_feedforward_s": 0.0, "slew_limit_bar_per_s": IDENT_SLEW_BAR_PER_S}
    h = Harness(ident_config(config, load_kg, open_loop))
    try:
        h.step(0.05)
        p_fits = fit_all(_record_steps(h, PRESSURE_LEVELS_BAR, PRESSURE_STEP_BAR,
                                       PRESSURE_RECORD_S, "pressure_bar"))
    finally:
        h.rig.close()
    p_model = mean_model(p_fits)
    kp, ki, kff = pressure_gains(p_model)
    closed = {"pid": {"kp": kp, "ki_per_s": ki, "kd_s": 0.0}, "rate_feedforward_s": kff,
              "slew_limit_bar_per_s": IDENT_SLEW_BAR_PER_S}
    h = Harness(ident_config(config, load_kg, closed))
    try:
        h.step(0.05)
        x_fits = fit_all(_record_steps(h, POSITION_LEVELS_BAR, POSITION_STEP_BAR,
                                       POSITION_RECORD_S, "length_mm"))
    finally:
        h.rig.close()
    x_model = mean_model(x_fits)
    kpx, kix = position_gains(x_model)
    if verbose:
        print_fits("Pressure loop: regulator setpoint -> measured pressure (PID off)",
                   "bar/bar", p_fits, p_model)
        print_fits("Position loop: pressure setpoint -> measured length (pressure loop "
                   "closed)", "mm/bar", x_fits, x_model)
    return Tuning(p_model, x_model, kp, ki, kff, kpx, kix)


def from_recording(path: str, loop: str, muscle: str | None) -> None:
    """Fit the steps found in a recording of an identification run on real hardware."""
    import pamd

    rec = pamd.open_recording(path)
    m = rec[muscle or next(iter(rec.muscles))]
    t = np.asarray(m["t_s"], dtype=float)
    if loop == "pressure":
        steps = steps_in(t, np.asarray(m["valve_cmd_bar"], dtype=float),
                         np.asarray(m["pressure_bar"], dtype=float), PRESSURE_RECORD_S)
    else:
        steps = steps_in(t, np.asarray(m["setpoint_bar"], dtype=float),
                         np.asarray(m["length_mm"], dtype=float), POSITION_RECORD_S)
    if not steps:
        what = "valve command" if loop == "pressure" else "setpoint"
        raise SystemExit(f"{path}: no steps of the {what} found (a step is a change of "
                         "more than 0.05 bar within 50 ms)")
    fits = fit_all(steps)
    model = mean_model(fits)
    unit = "bar/bar" if loop == "pressure" else "mm/bar"
    print_fits(f"{path}: {loop} loop", unit, fits, model)
    if loop == "pressure":
        kp, ki, kff = pressure_gains(model)
        print(f"control:\n  pid: {{kp: {kp:.3g}, ki_per_s: {ki:.3g}, kd_s: 0.0}}\n"
              f"  rate_feedforward_s: {kff:.3g}")
    else:
        kpx, kix = position_gains(model)
        print(f"control:\n  position:\n    pid: {{kp_bar_per_mm: {kpx:.3g}, "
              f"ki_bar_per_mm_s: {kix:.3g}, kd_bar_s_per_mm: 0.0}}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(REPO / "config" / "sim.yaml"),
                    help="rig config with a sim driver (default: config/sim.yaml)")
    ap.add_argument("--load-kg", type=float, default=None,
                    help="hanging load for the identification (default: the config's)")
    ap.add_argument("--recording", help="fit the steps of a recorded identification run "
                    "(real hardware) instead of running the simulated rig")
    ap.add_argument("--loop", choices=("pressure", "position"), default="pressure",
                    help="with --recording: which loop the recorded steps identify")
    ap.add_argument("--muscle", help="with --recording: the muscle (default: the first)")
    a = ap.parse_args()
    if a.recording:
        from_recording(a.recording, a.loop, a.muscle)
        return
    r = tune(a.config, a.load_kg)
    print("Gains (SIMC PI, tau_c = dead time; rate feedforward = dead time + tau):")
    print("control:")
    print(f"  pid: {{kp: {r.kp:.3g}, ki_per_s: {r.ki_per_s:.3g}, kd_s: 0.0}}")
    print(f"  rate_feedforward_s: {r.rate_feedforward_s:.3g}")
    print("  position:")
    print(f"    pid: {{kp_bar_per_mm: {r.kp_bar_per_mm:.3g}, ki_bar_per_mm_s: "
          f"{r.ki_bar_per_mm_s:.3g}, kd_bar_s_per_mm: 0.0}}")


if __name__ == "__main__":
    main()

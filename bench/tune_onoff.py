"""Tune on/off valve control from a step test on the rig: the PWM pressure loop's and
seed 004's sliding mode's settings (`muscles[].onoff`), never from the simulator's
parameters, only from what the sensors saw.

The procedure and its rules, each with its reason, are `pamd.client.tune.onoff_steps`'s (its
docstring): an identification run (the PWM's dead band opened to 1 bar, so it leaves
the valves to this script once the muscle holds 3 bar at 30 kg), then each valve in
turn, inflate then exhaust, a 40 ms pulse (the fill / vent rate), the PWM's shortest
pulse three times, alternating (half the smaller typical step, the mean of the three,
is the dead band; the encoder's count) and a 300 ms pulse (the valve speeds: the
boundary layer and lambda);
`response_s` is 5 PWM periods.

`pamd tune --loop onoff` runs the same pulses through the daemon (the `pulse` command,
timed in the tick) and reads them from the recording; this script runs them tick by
tick on the in-process harness, writing the valves' outputs itself, and applies the
same rules (`pamd.client.tune.onoff_steps.derive`). The shipped settings of
config/sim-onoff.yaml are its figures.

    python bench/tune_onoff.py [--config config/sim-onoff.yaml]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path
from typing import Any

import _lockdir  # noqa: F401  (the run's own rig-lock directory)
import numpy as np
import yaml

from pamd.client.tune.onoff_steps import (
    IDENT_DEAD_BAND_BAR,
    LEVEL_BAR,
    PULSES,
    SETTLE_AFTER_S,
    SETTLE_S,
    WINDOW_S,
    Measurement,
    derive,
    fastest,
    shortest_of,
    smallest_change_mm,
    typical_step_bar,
)
from pamd.config import load_config
from pamd.loop.control.actuation import OnOffActuation, min_pulse_s
from pamd.loop.devices.bindings import OutputBinding
from pamd.loop.harness import Harness

REPO = Path(__file__).resolve().parents[1]
DT = 0.001


def ident_harness(config: Path, load_kg: float) -> Harness:
    d: dict[str, Any] = yaml.safe_load(config.read_text())
    d["loop"]["clock"] = "virtual"
    d["loop"]["realtime"] = {"enabled": False}
    d.pop("recording", None)
    d["telemetry"] = {"enabled": False}
    m = d["muscles"][0]
    m["load_kg"] = load_kg
    m.setdefault("onoff", {})["dead_band_bar"] = IDENT_DEAD_BAND_BAR  # the identification run
    for drv in d["drivers"]:
        if drv["type"] == "sim":
            drv["options"]["muscles"][0]["load_kg"] = load_kg
    path = Path(tempfile.mkdtemp()) / "ident.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    h = Harness(load_config(str(path)))
    h.step(0.01)
    return h


class StepTest:
    def __init__(self, h: Harness) -> None:
        self.h = h
        self.m = h.ctrl.muscles[0]
        act = self.m.actuation
        assert isinstance(act, OnOffActuation), "the muscle is not on on/off valves"
        self.act = act
        self.lengths: list[float] = []

    def _avg(self) -> tuple[float, float]:
        ps, ls = [], []
        for _ in range(round(WINDOW_S / DT)):
            self.h.step(DT)
            ps.append(self.m.pressure_bar)
            ls.append(self.m.length_mm)
        self.lengths += ls
        return statistics.fmean(ps), statistics.fmean(ls)

    def pulse(self, out: OutputBinding, pulse_s: float, after_s: float
              ) -> tuple[float, float, float]:
        """(pressure step bar, length step mm, fastest speed mm/s) of one pulse."""
        p0, l0 = self._avg()
        trace: list[float] = []
        out.write_si(1.0)
        for _ in range(round(pulse_s / DT)):
            self.h.step(DT)
            trace.append(self.m.length_mm)
        out.write_si(0.0)
        for _ in range(round(after_s / DT)):
            self.h.step(DT)
            trace.append(self.m.length_mm)
        self.lengths += trace
        p1, l1 = self._avg()
        return p1 - p0, l1 - l0, fastest(np.asarray(trace), DT)[0]


def tune(config: Path, load_kg: float) -> dict[str, float]:
    h = ident_harness(config, load_kg)
    try:
        assert h.cmd("setpoint", muscle=h.ctrl.muscles[0].name, bar=LEVEL_BAR)["ok"]
        h.step(SETTLE_S)
        t = StepTest(h)
        cfg = h.cfg.muscle(t.m.name).onoff
        shortest = min_pulse_s(cfg)
        measured: list[Measurement] = []
        for p in PULSES:
            dp, _, speed = t.pulse(t.act.inflate if p.valve == "inflate" else t.act.exhaust,
                                   p.length_s(shortest), SETTLE_AFTER_S)
            measured.append(Measurement(p, dp, speed))  # its own ticks: as commanded
        count_mm = smallest_change_mm(np.asarray(t.lengths))
    finally:
        h.rig.close()
    dp_fill, dp_vent = (m.pressure_step_bar for m in measured[:2])
    v_fill, v_vent = (m.speed_mm_s for m in measured[-2:])
    fill_min, vent_min = (shortest_of(measured, v) for v in ("inflate", "exhaust"))
    print(f"step test at {LEVEL_BAR:g} bar, {load_kg:g} kg: 40 ms pulses {dp_fill:+.3f} / "
          f"{dp_vent:+.3f} bar; shortest pulses ({1e3 * shortest:g} ms) "
          f"{' '.join(f'{m.pressure_step_bar:+.4f}' for m in fill_min)} / "
          f"{' '.join(f'{m.pressure_step_bar:+.4f}' for m in vent_min)} bar (typical "
          f"{typical_step_bar(fill_min):+.4f} / {typical_step_bar(vent_min):+.4f}); valve "
          f"speeds {v_fill:.1f} / {v_vent:.1f} mm/s (inflate / exhaust); encoder count "
          f"{count_mm:g} mm")
    return derive(measured, count_mm, cfg.pwm_period_s)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, default=REPO / "config" / "sim-onoff.yaml")
    ap.add_argument("--load-kg", type=float, default=30.0)
    a = ap.parse_args()
    gains = tune(a.config, a.load_kg)
    print("muscles[].onoff:")
    for k, v in gains.items():
        print(f"  {k}: {v:.3g}")


if __name__ == "__main__":
    main()

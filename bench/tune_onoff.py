"""Tune on/off valve control from a step test on the rig: the PWM pressure loop's and
seed 004's sliding mode's settings (`muscles[].onoff`), never from the simulator's
parameters, only from what the sensors saw.

The step test (an *identification run*: the PWM's dead band opened to 1 bar, so it
leaves the valves to this script once the muscle holds 3 bar at 30 kg), each valve in
turn, inflate then exhaust:

1. a 40 ms pulse: the pressure step over the pulse's length is the valve's rate
   (`fill_rate_bar_per_s`, `vent_rate_bar_per_s`; the duty's gain);
2. the shortest pulse the PWM sends (`pamd.control.actuation.min_pulse_s`): half the
   smaller of its two pressure steps is `dead_band_bar` (no pulse can place the
   pressure closer), the smallest length change seen is the encoder's count;
3. a 300 ms pulse: the fastest length change seen (over 50 ms) is the valve's speed
   on the muscle, held open (the muscle reaches it within about 0.2 s; a 150 ms pulse
   measured the exhaust at half its speed, issue 29). The *faster* of the two valves
   sets the boundary layer (`position_boundary_mm_s`): the duty s / boundary is then a
   velocity feedback of gain (valve speed / boundary) <= 1 for both valves. With the
   boundary at the slower valve's underestimated speed (14.2 mm/s against 43 and 31
   mm/s) the gain was 2-3, the surface left the layer at every swing and the valves
   relayed fully open against the hanging load's oscillation: the +-2 mm hunting of
   issue 29. `position_lambda_per_s` = boundary / 3 mm puts the layer's edge 3 mm from
   a target at rest (chosen on issue 14's single 10 mm step from 3 bar at 30 kg, not
   on issue 29's plateaus: 5 mm left that step 0.22 mm short after 6 s, the last
   creep pulses too small for the stuck muscle; 1 mm relays most of a 5 mm step);
   `position_hold_band_mm` is one encoder count.

`response_s` is 5 PWM periods (the PWM averages over a few). Each measurement is
the mean of 50 samples before and after the pulse, so sensor noise averages out.

    python bench/tune_onoff.py [--config config/sim-onoff.yaml]

On real hardware run the same pulses from a script on `pamd cmd` (or read them from
a recording) and apply the same rules.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path
from typing import Any

import _lockdir  # noqa: F401  (the run's own rig-lock directory)
import yaml

from pamd.config import load_config
from pamd.control.actuation import OnOffActuation, min_pulse_s
from pamd.harness import Harness
from pamd.rig import OutputBinding

REPO = Path(__file__).resolve().parents[1]
DT = 0.001
LEVEL_BAR = 3.0
RATE_PULSE_S = 0.04
SPEED_PULSE_S = 0.3
SPEED_WINDOW_S = 0.05  # a speed over 50 ms: 0.2 mm/s per encoder count
LAYER_MM = 3.0  # the boundary layer's edge from a target at rest
RESPONSE_PERIODS = 5.0


def ident_harness(config: Path, load_kg: float) -> Harness:
    d: dict[str, Any] = yaml.safe_load(config.read_text())
    d["loop"]["clock"] = "virtual"
    d["loop"]["realtime"] = {"enabled": False}
    d.pop("recording", None)
    d["telemetry"] = {"enabled": False}
    m = d["muscles"][0]
    m["load_kg"] = load_kg
    m.setdefault("onoff", {})["dead_band_bar"] = 1.0  # the identification run
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

    def _avg(self, n: int = 50) -> tuple[float, float]:
        ps, ls = [], []
        for _ in range(n):
            self.h.step(DT)
            ps.append(self.m.pressure_bar)
            ls.append(self.m.length_mm)
        self.lengths += ls
        return statistics.fmean(ps), statistics.fmean(ls)

    def pulse(self, out: OutputBinding, pulse_s: float, after_s: float = 0.2
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
        w = round(SPEED_WINDOW_S / DT)
        speed = max(abs(trace[i + w] - trace[i]) / SPEED_WINDOW_S for i in range(len(trace) - w))
        return p1 - p0, l1 - l0, speed


def tune(config: Path, load_kg: float) -> dict[str, float]:
    h = ident_harness(config, load_kg)
    try:
        assert h.cmd("setpoint", muscle=h.ctrl.muscles[0].name, bar=LEVEL_BAR)["ok"]
        h.step(2.0)
        t = StepTest(h)
        cfg = h.cfg.muscle(t.m.name).onoff
        dp_fill, _, _ = t.pulse(t.act.inflate, RATE_PULSE_S)
        dp_vent, _, _ = t.pulse(t.act.exhaust, RATE_PULSE_S)
        shortest = min_pulse_s(cfg)
        dp_fill_min, _, _ = t.pulse(t.act.inflate, shortest)
        dp_vent_min, _, _ = t.pulse(t.act.exhaust, shortest)
        _, _, v_fill = t.pulse(t.act.inflate, SPEED_PULSE_S, 0.5)
        _, _, v_vent = t.pulse(t.act.exhaust, SPEED_PULSE_S, 0.5)
        steps = sorted({round(abs(b - a), 6) for a, b in zip(t.lengths, t.lengths[1:],
                                                             strict=False)} - {0.0})
        count_mm = steps[0] if steps else 0.01
    finally:
        h.rig.close()
    boundary = max(v_fill, v_vent)  # velocity gain <= 1 for both valves
    out = {
        "fill_rate_bar_per_s": dp_fill / RATE_PULSE_S,
        "vent_rate_bar_per_s": -dp_vent / RATE_PULSE_S,
        "response_s": RESPONSE_PERIODS * cfg.pwm_period_s,
        "dead_band_bar": 0.5 * min(abs(dp_fill_min), abs(dp_vent_min)),
        "position_lambda_per_s": boundary / LAYER_MM,
        "position_boundary_mm_s": boundary,
        "position_hold_band_mm": count_mm,
    }
    print(f"step test at {LEVEL_BAR:g} bar, {load_kg:g} kg: 40 ms pulses {dp_fill:+.3f} / "
          f"{dp_vent:+.3f} bar; shortest pulse ({1e3 * shortest:g} ms) {dp_fill_min:+.4f} / "
          f"{dp_vent_min:+.4f} bar; valve speeds {v_fill:.1f} / {v_vent:.1f} mm/s "
          f"(inflate / exhaust); encoder count {count_mm:g} mm")
    return out


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

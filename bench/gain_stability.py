"""Gains judged against stability (issue 47, item 1): does the judgement foretell what
the rig does? For gain sets around the boundary, the margins `pamd.config.stability`
computes on the default plant (the simulated DMSP-20-200's measured response, never
the simulator's parameters) beside what the simulated rig does with them: the pressure
loop held at 3 bar, the position loop at a length (position mode, the PID alone), the
rms swing of the last second after 3 s (virtual clock, through the harness; the sets
the config refuses run with `safety.relax_stability`).

    python bench/gain_stability.py
"""

from __future__ import annotations

import logging

import _common  # noqa: F401  (OPENBLAS_NUM_THREADS, the rig-lock directory)
import numpy as np
from _common import sim_config

from pamd.config.control_schema import DEFAULT_POSITION_PLANT, DEFAULT_PRESSURE_PLANT
from pamd.config.stability import Plant, margins, pid
from pamd.harness import Harness

PRESSURE = [(0.516, 41.2), (0.516, 70.0), (0.516, 100.0), (0.516, 120.0), (0.516, 150.0),
            (0.516, 400.0), (1.0, 41.2), (1.5, 41.2), (1.8, 41.2), (2.2, 41.2),
            (19.9, 1999.0)]
POSITION = [(0.0656, 2.08), (0.1, 2.08), (0.15, 2.08), (0.2, 2.08), (0.25, 2.08),
            (0.0656, 5.0), (0.0656, 8.0), (0.0656, 12.0), (0.0656, 30.0), (0.5, 2.08)]


def swing(h: Harness, column: str) -> float:
    values = np.array([r["m1"][column] for r in h.records[-1000:]])
    return float(values.std())


def main() -> None:
    logging.disable(logging.WARNING)  # each refused set's warning: its verdict is printed
    period = 1e-3
    pp = DEFAULT_PRESSURE_PLANT
    plant = Plant(pp.gain_bar_per_bar, pp.lag_s, pp.dead_time_s)
    print("pressure loop, 3 bar (default plant: gain 0.95, lag 12.5 ms, dead 12.8 ms)")
    print(f"  {'kp':>6s} {'ki 1/s':>7s}  {'judged':44s} {'verdict':8s} {'rms bar':>8s}")
    for kp, ki in PRESSURE:
        m = margins(pid(kp, ki, 0.0, 30.0, period), plant, period)
        h = Harness(sim_config(control={"pid": {"kp": kp, "ki_per_s": ki, "kd_s": 0.0}},
                               safety={"relax_stability": True}))
        h.keep = True
        h.cmd("setpoint", muscle="m1", bar=3.0)
        h.step(3.0)
        verdict = "refused" if m.refused() else "warned" if m.warned() else "ok"
        print(f"  {kp:6.3g} {ki:7.4g}  {m.text()[:44]:44s} {verdict:8s} "
              f"{swing(h, 'pressure_bar'):8.4f}")
        h.rig.close()
    xp = DEFAULT_POSITION_PLANT
    plant = Plant(abs(xp.gain_mm_per_bar), xp.lag_s, xp.dead_time_s)
    print("position loop, PID alone at 10 % contraction, 30 kg (default plant: -6.6 mm/bar, lag "
          "31.6 ms, dead 36.2 ms)")
    print(f"  {'kp':>6s} {'ki':>7s}  {'judged':44s} {'verdict':8s} {'rms mm':>8s} "
          f"{'setpoint rms bar':>16s}")
    for kp, ki in POSITION:
        m = margins(pid(kp, ki, 0.0, 10.0, period), plant, period)
        h = Harness(sim_config(control={"position": {"pid": {
            "kp_bar_per_mm": kp, "ki_bar_per_mm_s": ki, "kd_bar_s_per_mm": 0.0}}},
            safety={"relax_stability": True}))
        h.keep = True
        h.step(0.5)
        h.cmd("mode", muscle="m1", mode="position", feedforward=False)
        h.cmd("profile", muscle="m1", kind="constant", to_contraction=0.1, duration_s=10)
        h.step(4.0)
        verdict = "refused" if m.refused() else "warned" if m.warned() else "ok"
        print(f"  {kp:6.3g} {ki:7.4g}  {m.text()[:44]:44s} {verdict:8s} "
              f"{swing(h, 'length_mm'):8.4f} {swing(h, 'setpoint_bar'):16.4f}")
        h.rig.close()


if __name__ == "__main__":
    main()

"""Gains judged against stability (issue 47, item 1): does the judgement foretell what
the rig does? For gain sets around the boundary, the margins `pamd.config.stability`
computes on the default plant (the simulated DMSP-20-200's measured response, never
the simulator's parameters) beside what the simulated rig does with them: the pressure
loop held at 3 bar, the position loop at a length and after a 4 mm step of it
(position mode, the PID alone), the rms swing of the last second after 3 s (virtual
clock, through the harness; the sets the config refuses run with
`safety.relax_stability`). And why the position loop's integral is warned about, not
refused: the position plant's response measured by amplitude (sines of the pressure
setpoint), against the fit of 0.5 bar steps it is judged on.

    python bench/gain_stability.py
"""

from __future__ import annotations

import cmath
import logging
import math

import _common  # noqa: F401  (OPENBLAS_NUM_THREADS, the rig-lock directory)
import numpy as np
from _common import sim_config

from pamd.config.control_schema import DEFAULT_POSITION_PLANT, DEFAULT_PRESSURE_PLANT
from pamd.config.gains import Judged, judge
from pamd.config.stability import Plant, margins, pid
from pamd.loop.harness import Harness

PRESSURE = [(0.516, 41.2), (0.516, 70.0), (0.516, 100.0), (0.516, 120.0), (0.516, 150.0),
            (0.516, 400.0), (1.0, 41.2), (1.5, 41.2), (1.8, 41.2), (2.2, 41.2),
            (19.9, 1999.0)]
POSITION = [(0.0656, 2.08), (0.1, 2.08), (0.15, 2.08), (0.2, 2.08), (0.25, 2.08),
            (0.35, 2.08), (0.5, 2.08), (0.0656, 5.0), (0.0656, 8.0), (0.0656, 12.0),
            (0.0656, 16.0), (0.0656, 24.0), (0.0656, 40.0), (0.15, 8.0), (0.25, 8.0)]
#: the position plant's response measured at these (Hz, bar around 3 bar)
FREQUENCIES = (1.0, 2.0, 4.0, 8.0)
AMPLITUDES = (0.05, 0.2, 0.5)


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
    position(period)


def harmonic(t: np.ndarray, x: np.ndarray, f_hz: float) -> complex:
    """The first harmonic of `x` at `f_hz` (a least-squares fit beside an offset and a
    drift: the length creeps after a move)."""
    a = np.column_stack([np.ones_like(t), t, np.cos(2 * np.pi * f_hz * t),
                         np.sin(2 * np.pi * f_hz * t)])
    c = np.linalg.lstsq(a, x, rcond=None)[0]
    return complex(c[2], -c[3])


def response(f_hz: float, amp_bar: float) -> complex:
    """The rig's pressure setpoint -> length response at `f_hz`, measured: a sine of
    the setpoint of +-`amp_bar` around 3 bar (pressure mode, the pressure loop as
    configured, the slew limit out of the way), settled, its harmonics compared."""
    h = Harness(sim_config(control={"slew_limit_bar_per_s": 500.0}))
    h.keep = True
    h.cmd("setpoint", muscle="m1", bar=3.0)
    h.step(8.0)  # the length creeps for seconds after a move (friction)
    h.cmd("profile", muscle="m1", shape="sine", min_bar=3.0 - amp_bar, max_bar=3.0 + amp_bar,
          freq_hz=f_hz, cycles=10000)
    h.step(max(1.0, 3.0 / f_hz))
    h.records.clear()
    h.step(max(4, int(2 * f_hz)) / f_hz)
    t = np.array([r["t_s"] for r in h.records])
    length = np.array([r["m1"]["length_mm"] for r in h.records])
    sp = np.array([r["m1"]["setpoint_bar"] for r in h.records])
    h.rig.close()
    return harmonic(t, length, f_hz) / harmonic(t, sp, f_hz)


def position(period: float) -> None:
    """Why the position loop's integral is warned about, not refused
    (`pamd.config.gains`): the rig's measured response by amplitude against the fit,
    then gain sets around the boundary, each verdict beside what the rig does."""
    xp = DEFAULT_POSITION_PLANT
    plant = Plant(abs(xp.gain_mm_per_bar), xp.lag_s, xp.dead_time_s)
    print("position plant, pressure setpoint -> length at 3 bar, 30 kg: measured by "
          "amplitude vs the fit of 0.5 bar steps (-6.6 mm/bar, lag 31.6 ms, dead 36.2 ms)")
    print(f"  {'f Hz':>5s} {'fit mm/bar, deg':>17s}" + "".join(
        f" {f'+-{a:g} bar: mm/bar, deg':>23s}" for a in AMPLITUDES))
    for f in FREQUENCIES:
        s = 2j * cmath.pi * f
        fit = plant.gain * cmath.exp(-plant.dead_time_s * s) / (plant.lag_s * s + 1.0)
        cells = [f"{abs(fit):9.2f} {math.degrees(cmath.phase(fit)):7.1f}"]
        for a in AMPLITUDES:
            g = -response(f, a)  # more pressure, shorter: the loop's sign
            cells.append(f"{abs(g):15.2f} {math.degrees(cmath.phase(g)):7.1f}")
        print(f"  {f:5.3g} " + " ".join(cells))
    print("position loop, PID alone at 10 % contraction, 30 kg (the rms swing of the last "
          "of 5 s); then a 4 mm step of the target (to 12 %; of the last of 3 s)")
    print(f"  {'kp':>6s} {'ki':>5s}  {'judged (whole loop)':44s} {'verdict':8s} "
          f"{'hold mm':>8s} {'step mm':>8s} {'setpoint bar':>12s}")
    for kp, ki in POSITION:
        j = Judged("control.position.pid", None, "position", "", pid(kp, ki, 0.0, 10.0, period),
                   plant, "", period, "", pid(kp, 0.0, 0.0, 10.0, period))
        v = judge(j)
        h = Harness(sim_config(control={"position": {"pid": {
            "kp_bar_per_mm": kp, "ki_bar_per_mm_s": ki, "kd_bar_s_per_mm": 0.0}}},
            safety={"relax_stability": True}))
        h.keep = True
        h.step(0.5)
        h.cmd("mode", muscle="m1", mode="position", feedforward=False)
        h.cmd("profile", muscle="m1", shape="constant", to_contraction=0.1, duration_s=5)
        h.step(5.0)  # the ramp to the target, then the hold
        hold = swing(h, "length_mm")
        h.cmd("profile", muscle="m1", shape="constant", to_contraction=0.12, duration_s=10)
        h.step(3.0)
        verdict = {"integral": "warned*"}.get(v.outcome, v.outcome)
        print(f"  {kp:6.3g} {ki:5.3g}  {v.margins.text()[:44]:44s} {verdict:8s} "
              f"{hold:8.4f} {swing(h, 'length_mm'):8.4f} {swing(h, 'setpoint_bar'):12.4f}")
        h.rig.close()
    print("  warned*: refused margins by the integral alone (pamd.config.gains): loaded "
          "with a warning")

if __name__ == "__main__":
    main()

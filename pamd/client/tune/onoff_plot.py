"""`pamd tune --loop onoff --plot FILE`: one PNG of the step test of every muscle
tuned. Each pulse has a column of its own (inflate, exhaust x 40 ms, the PWM's
shortest three times each, 300 ms, in the order they ran; a shortest pulse's title
says which repeat it is, and "left out" on one whose step the typical step does not
count: `pamd.client.tune.onoff_steps.counted`), the
measured pressure above and the length below, against the time from the valve's
opening (ms):

- the valve-open interval shaded (blue: inflate, orange: exhaust);
- the means before and after (`WINDOW_S` each, both valves shut) as thick black
  segments over the samples they average, the step between them written in the
  panel's corner;
- on the 300 ms pulses' lengths, the fastest length change (over `SPEED_WINDOW_S`) as
  a red segment, its speed written in a lower corner.

So a glance tells a sound measurement (the trace flat through both windows, a clear
step between) from one that is not: a pulse that moved nothing (its step written in
red, with what the check says, the panel framed red), a noisy or drifting baseline
(the trace wandering through a window, off its black segment). The data is the
analysis's (`PulseResponse.trace`): the recording is not read again.
"""

from __future__ import annotations

import textwrap
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from pamd.client.tune.onoff_steps import (
    SHORTEST_REPEATS,
    SPEED_PULSE_S,
    SPEED_WINDOW_S,
    WINDOW_S,
    PulseResponse,
    StepTest,
    counted,
    measurements,
    shortest_of,
    unsound,
)
from pamd.client.tune.tune_report import pyplot
from pamd.wire.atomic import save_figure

if TYPE_CHECKING:  # matplotlib is the optional extra: its types only
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

VALVE_COLOUR = {"inflate": "tab:blue", "exhaust": "tab:orange"}
PANEL_IN = (2.7, 2.0)  # one panel's width and height (inches)
DPI = 110


def plot_onoff(path: str, tests: dict[str, StepTest], level_bar: float) -> None:
    """Write the PNG of the step tests (by muscle) at `level_bar` to `path`."""
    plt = pyplot()
    fig = onoff_figure(plt, tests, level_bar)
    save_figure(fig, path, DPI)  # whole or not at all (pamd.wire.atomic)
    plt.close(fig)


def onoff_figure(plt: ModuleType, tests: dict[str, StepTest], level_bar: float) -> Figure:
    """The figure: per muscle a row of pressure panels over a row of length panels,
    one column per pulse. The artists carry gids: `open` (the shaded interval),
    `before` and `after` (the means), `fastest` (the 300 ms pulses' lengths)."""
    n = len(tests[next(iter(tests))].responses()) if tests else 0
    height_in = PANEL_IN[1] * 2 * len(tests) + 0.9
    fig: Figure
    fig, axes = plt.subplots(  # fixed margins: tight_layout would measure every text
        2 * len(tests), n, squeeze=False, figsize=(PANEL_IN[0] * n, height_in),
        gridspec_kw={"left": 0.045, "right": 0.99, "top": 1.0 - 0.6 / height_in,
                     "bottom": 0.45 / height_in, "wspace": 0.32, "hspace": 0.42})
    for row, (muscle, test) in enumerate(tests.items()):
        for col, r in enumerate(test.responses()):
            p_ax, l_ax = axes[2 * row][col], axes[2 * row + 1][col]
            why = unsound(r)
            speed = r.pulse.pulse_s == SPEED_PULSE_S
            tr = r.trace
            _panel(p_ax, r, tr.pressure_bar, tr.pressure_before_bar, r.pressure_step_bar,
                   "bar", ".4f", None if speed else why)
            _panel(l_ax, r, tr.length_mm, tr.length_before_mm, r.length_step_mm, "mm",
                   ".3f", why if speed else None)
            if speed:
                _fastest(l_ax, r)
            p_ax.set_title(f"{muscle}: {title(test, r)}", fontsize=9)
            l_ax.set_xlabel("time from the valve opening (ms)", fontsize=8)
        axes[2 * row][0].set_ylabel(f"{muscle}: pressure (bar)", fontsize=8)
        axes[2 * row + 1][0].set_ylabel(f"{muscle}: length (mm)", fontsize=8)
    fig.suptitle(f"pamd tune --loop onoff: the step test at {level_bar:g} bar. Shaded: the "
                 "valve open; black: the means before and after (both valves shut); red: "
                 f"the fastest length change over {1e3 * SPEED_WINDOW_S:g} ms", fontsize=9)
    return fig


def title(test: StepTest, r: PulseResponse) -> str:
    """A pulse's column title: its valve and length; a shortest pulse's repeat (k/3),
    and "left out" on one the dead band's typical step does not count."""
    text = f"{r.pulse.valve} {1e3 * r.pulse_s:.0f} ms"
    if r.pulse.pulse_s is not None:
        return text
    repeats = [s for s in test.shortest if s.pulse.valve == r.pulse.valve]
    k = next(k for k, s in enumerate(repeats) if s is r)
    kept = counted(shortest_of(measurements(test), r.pulse.valve))[k]
    return f"{text} {k + 1}/{SHORTEST_REPEATS}" + ("" if kept else ", left out")


def _panel(ax: Axes, r: PulseResponse, y: np.ndarray, before: float, step: float,
           unit: str, fmt: str, why: str | None) -> None:
    """One quantity around one pulse: its trace, the valve open, the means and the step
    (with `why` it is unsound: said in red)."""
    tr = r.trace
    ax.plot(1e3 * tr.t_s, y, lw=0.7, color="0.35")
    ax.axvspan(0.0, 1e3 * r.pulse_s, color=VALVE_COLOUR[r.pulse.valve], alpha=0.3, lw=0,
               gid="open")
    ax.plot([-1e3 * WINDOW_S, 0.0], [before, before], "k-", lw=2.5, gid="before")
    a = 1e3 * tr.after_from_s
    ax.plot([a, a + 1e3 * WINDOW_S], [before + step] * 2, "k-", lw=2.5, gid="after")
    text = f"step {step:{'+' + fmt}} {unit}"
    if why is not None:
        text += "\n" + textwrap.fill(why, 28)
        for spine in ax.spines.values():
            spine.set_edgecolor("red")
    _note(ax, step, text, "red" if why is not None else "black")
    ax.tick_params(labelsize=7)
    ax.ticklabel_format(axis="y", useOffset=False)  # the level itself, not an offset
    ax.grid(True, alpha=0.3)


def _fastest(ax: Axes, r: PulseResponse) -> None:
    """The fastest length change of a 300 ms pulse: a red segment over its window."""
    tr = r.trace
    t = np.array([tr.fastest_from_s, tr.fastest_from_s + SPEED_WINDOW_S])
    ax.plot(1e3 * t, np.interp(t, tr.t_s, tr.length_mm), color="red", lw=2.5,
            gid="fastest")
    x, ha = (0.97, "right") if r.length_step_mm >= 0.0 else (0.03, "left")  # the corner free
    ax.text(x, 0.05, f"fastest {r.speed_mm_s:.1f} mm/s", transform=ax.transAxes, ha=ha,
            color="red", fontsize=7)


def _note(ax: Axes, step: float, text: str, colour: str) -> None:
    """`text` in the upper corner the trace leaves free: left when it rises."""
    x, ha = (0.03, "left") if step >= 0.0 else (0.97, "right")
    ax.text(x, 0.95, text, transform=ax.transAxes, ha=ha, va="top", fontsize=7, color=colour,
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})

"""The figures of a run, without a model (`pamd plot`): per muscle, pressure and
setpoint against time, length and its target, force, and the pressure-contraction
hysteresis loop of each load (seeds 000 and 003). One figure per PNG file, sized and
labelled for print (units on every axis, a legend wherever there is more than one line).

matplotlib is the optional `plot` extra, imported here only (Agg backend).
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from pamd.client.recording import MuscleData, Recording
from pamd.wire.atomic import save_figure
from pamd.wire.errors import RecordingError

if TYPE_CHECKING:  # matplotlib is the optional extra: its types only
    from matplotlib.figure import Figure

FIGSIZE = (8.0, 4.5)
DPI = 150
#: Time series are drawn through the least and largest value of each of this many
#: equal runs of samples, in the order they occur (min/max decimation): twice the
#: figure's 1200 pixel columns, so every column shows the span the full series has
#: there, as drawing every tick would, at a small part of the cost (a collection's
#: 375 000 ticks took matplotlib seconds per figure).
SERIES_BUCKETS = 2400
#: The hysteresis loops draw at most this many points per load (every k-th running
#: tick): a 0.05 Hz sweep of three cycles at 1 kHz keeps every fourth tick, 2500 dots a
#: branch across the figure's 900 pixels, each dot (1.5 pt) three pixels wide.
LOOP_POINTS = 15_000


def _pyplot() -> ModuleType:
    """matplotlib.pyplot on the Agg backend (the module: its functions are typed by
    matplotlib, reached through the module's attributes)."""
    try:
        import matplotlib
    except ImportError:
        raise RecordingError("plots need matplotlib: pip install 'pamd[plot]'") from None
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def timeline(m: MuscleData) -> tuple[np.ndarray, bool]:
    """The time axis: t_s, with files whose clock restarts placed end to end."""
    t = np.asarray(m["t_s"], dtype=np.float64).copy()
    back = np.flatnonzero(np.diff(t) < 0)
    for i in back:
        t[i + 1:] += t[i] - t[i + 1] + (t[i] - t[i - 1] if i > 0 else 0.0)
    return t, bool(len(back))


def write_plots(rec: Recording, prefix: str, muscles: list[str] | None = None) -> list[str]:
    """PREFIX_<muscle>_{pressure,length,force,hysteresis}.png; returns the paths."""
    plt = _pyplot()
    d = os.path.dirname(prefix)
    if d:
        os.makedirs(d, exist_ok=True)
    out: list[str] = []
    for name in muscles or list(rec.muscles):
        m = rec[name]
        if len(m) == 0:
            raise RecordingError(f"{rec.source}: muscle {name} has no ticks")
        t, joined = timeline(m)
        xlabel = "time [s]" + (" (files placed end to end)" if joined else "")
        where = f"{name}, {os.path.basename(rec.source.rstrip(os.sep))}"
        base = f"{prefix}_{name}"
        out.append(_series(plt, f"{base}_pressure.png", t, xlabel, "pressure [bar]",
                           [(m["pressure_bar"], "measured pressure", "tab:blue", "-"),
                            (m["setpoint_bar"], "setpoint", "tab:orange", "--")],
                           f"Pressure and setpoint ({where})"))
        lines = [(m["length_mm"], "measured length", "tab:blue", "-")]
        if np.isfinite(m["target_length_mm"]).any():
            lines.append((m["target_length_mm"], "length target", "tab:orange", "--"))
        out.append(_series(plt, f"{base}_length.png", t, xlabel, "length [mm]", lines,
                           f"Length{' and target' if len(lines) > 1 else ''} ({where})"))
        out.append(_series(plt, f"{base}_force.png", t, xlabel, "force [N]",
                           [(m["force_n"], "measured force", "tab:green", "-")],
                           f"Force ({where})"))
        out.append(_hysteresis(plt, f"{base}_hysteresis.png", m,
                               f"Pressure-contraction hysteresis ({where})"))
    return out


def _series(plt: ModuleType, path: str, t: np.ndarray, xlabel: str, ylabel: str,
            lines: list[tuple[np.ndarray, str, str, str]], title: str) -> str:
    fig, ax = plt.subplots(figsize=FIGSIZE)
    for y, label, color, style in lines:
        ax.plot(*envelope(t, y), style, color=color, lw=1.2, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    if len(lines) > 1:
        ax.legend(loc="best")
    return _save(fig, plt, path)


def envelope(t: np.ndarray, y: np.ndarray, buckets: int = SERIES_BUCKETS
             ) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) through the least and largest y of each of `buckets` equal runs of
    samples, at their own times and in their order (`SERIES_BUCKETS`); a series no
    longer than four points a bucket as it is. A run of NaN stays a gap."""
    n = len(y)
    if n <= 4 * buckets:
        return t, y
    k = -(-n // buckets)  # samples a run
    rows = -(-n // k)
    pad = rows * k - n
    yy = np.concatenate([np.asarray(y, dtype=np.float64), np.full(pad, np.nan)])
    yy = yy.reshape(rows, k)
    empty = np.isnan(yy).all(axis=1)
    lo = np.argmin(np.where(np.isnan(yy), np.inf, yy), axis=1) + np.arange(rows) * k
    hi = np.argmax(np.where(np.isnan(yy), -np.inf, yy), axis=1) + np.arange(rows) * k
    first, second = np.minimum(lo, hi), np.maximum(lo, hi)
    idx = np.clip(np.stack([first, second], axis=1).reshape(-1), 0, n - 1)
    ys = np.asarray(y, dtype=np.float64)[idx]
    ys[np.repeat(empty, 2)] = np.nan
    return np.asarray(t)[idx], ys


def hysteresis_loops(m: MuscleData) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(load label, pressure [bar], contraction [%]) of the running ticks, per load."""
    running = m.states() == "RUNNING"
    loads = m["load_kg"]
    keys = sorted({float(x) for x in loads[running]}, key=lambda x: (np.isnan(x), x))
    out = []
    for load in keys:
        sel = running & (np.isnan(loads) if np.isnan(load) else loads == load)
        label = "load unknown" if np.isnan(load) else f"{load:g} kg"
        out.append((label, m["pressure_bar"][sel], 100.0 * m["contraction"][sel]))
    return out


def _hysteresis(plt: ModuleType, path: str, m: MuscleData, title: str) -> str:
    """Contraction against measured pressure while running, one loop per load."""
    loops = hysteresis_loops(m)
    fig, ax = plt.subplots(figsize=(6.5, 5.0))
    cmap = plt.get_cmap("viridis", max(2, len(loops)))
    for k, (label, p, c) in enumerate(loops):
        every = max(1, -(-len(p) // LOOP_POINTS))
        ax.plot(p[::every], c[::every], ".", ms=1.5, color=cmap(k), label=label)
    if not loops:
        ax.text(0.5, 0.5, "no running ticks (no profile ran)", ha="center",
                transform=ax.transAxes)
    ax.set_xlabel("pressure [bar]")
    ax.set_ylabel("contraction [%]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    if loops:
        ax.legend(loc="best", title="hanging load", markerscale=6)
    return _save(fig, plt, path)


def _save(fig: Figure, plt: ModuleType, path: str) -> str:
    fig.tight_layout()
    save_figure(fig, path, DPI)  # whole or not at all (pamd.wire.atomic)
    plt.close(fig)
    return path

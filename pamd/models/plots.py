"""Figures of several models judged on the same data: predictions overlaid on the
measurement, and their errors over time (matplotlib, optional, as `pamd.models.anfis.anfis_plots`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from pamd.models.anfis.anfis_plots import _label, _pyplot, _save
from pamd.models.compare import Judged


def write_overlay(prefix: str, judged: Sequence[Judged], t_s: np.ndarray, y: np.ndarray,
                  title: str = "") -> list[str]:
    """PREFIX_prediction.png (measurement and every model) and PREFIX_error.png."""
    plt = _pyplot()
    d = os.path.dirname(prefix)
    if d:
        os.makedirs(d, exist_ok=True)
    o = judged[0].model.output
    fig, ax = plt.subplots(figsize=(10, 5))
    ax.plot(t_s, y, ".", ms=2.5, label="measured", color="k")
    for j in judged:
        ax.plot(t_s, j.y_hat, "-", lw=1.0,
                label=f"{j.model.kind} ({os.path.basename(j.file)}), RMSE "
                      f"{j.metrics['rmse']:.3g}")
    ax.set_xlabel("time [s] (runs placed end to end)")
    ax.set_ylabel(_label(o.name, o.unit))
    ax.set_title(title or f"{o.name}: models against measurement")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    out = [_save(fig, plt, prefix + "_prediction.png")]
    fig, ax = plt.subplots(figsize=(10, 4))
    for j in judged:
        ax.plot(t_s, j.y_hat - y, "-", lw=0.8,
                label=f"{j.model.kind} ({os.path.basename(j.file)}): max dev "
                      f"{j.metrics['max_deviation_pct']:.2f} %")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("time [s] (runs placed end to end)")
    ax.set_ylabel(f"model - measured [{o.unit}]" if o.unit else "model - measured")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    out.append(_save(fig, plt, prefix + "_error.png"))
    return out

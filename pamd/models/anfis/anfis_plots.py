"""PNG figures of a model and its evaluation, in the manner of seed 000: the training
curve (its figure 7), the fuzzy surface (figure 8), prediction against measurement
(figure 10), plus the error over time and the membership functions.

matplotlib is an optional dependency (`pip install pamd[plot]`); it is imported
here only, with the non-interactive Agg backend, so nothing else in pamd needs it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from pamd.models.anfis.membership import log_membership
from pamd.models.anfis.model import AnfisModel
from pamd.wire.atomic import save_figure
from pamd.wire.errors import ModelError


def _pyplot() -> Any:  # Any: matplotlib.pyplot, imported lazily (heavy third party)
    try:
        import matplotlib
    except ImportError:
        raise ModelError("plots need matplotlib: pip install 'pamd[plot]' (or matplotlib)"
                         ) from None
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def require_matplotlib() -> None:
    """Raise the plots' `ModelError` now if matplotlib cannot be imported: a command
    that will plot checks this before its long work, not after it."""
    _pyplot()


def _label(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def write_plots(prefix: str, model: AnfisModel, t_s: np.ndarray, y: np.ndarray,
                y_hat: np.ndarray, clipped: np.ndarray | None = None,
                title: str = "") -> list[str]:
    """Write PREFIX_prediction.png, _error.png, _membership.png, _surface.png (and
    _training.png when the model file holds a training curve); returns the paths."""
    plt = _pyplot()
    d = os.path.dirname(prefix)
    if d:
        os.makedirs(d, exist_ok=True)
    out = []
    o = model.output
    ylab = _label(o.name, o.unit)

    fig, ax = plt.subplots(figsize=(9, 4.5))
    ax.plot(t_s, y, ".", ms=2.5, label="measured", color="tab:blue")
    ax.plot(t_s, y_hat, ".", ms=2.5, label="model", color="tab:orange")
    if clipped is not None and clipped.any():
        ax.plot(t_s[clipped], y_hat[clipped], "x", ms=4, color="tab:red",
                label="inputs clipped to the training range")
    ax.set_xlabel("time [s] (runs placed end to end)")
    ax.set_ylabel(ylab)
    ax.set_title(title or f"{o.name}: model against measurement")
    ax.legend(loc="best")
    ax.grid(alpha=0.3)
    out.append(_save(fig, plt, prefix + "_prediction.png"))

    fig, ax = plt.subplots(figsize=(9, 3.5))
    err = y_hat - y
    ax.plot(t_s, err, ".", ms=2.5, color="tab:red")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("time [s] (runs placed end to end)")
    ax.set_ylabel(f"model - measured [{o.unit}]" if o.unit else "model - measured")
    rmse = float(np.sqrt(np.mean(err * err)))
    ax.set_title(f"error: RMSE {rmse:.4g}, max |error| {float(np.max(np.abs(err))):.4g}")
    ax.grid(alpha=0.3)
    out.append(_save(fig, plt, prefix + "_error.png"))

    out.append(membership_plot(prefix + "_membership.png", model))
    out.append(surface_plot(prefix + "_surface.png", model))
    curve = model.provenance.get("training_curve")
    if isinstance(curve, dict) and curve.get("train_rmse"):
        out.append(training_plot(prefix + "_training.png", curve))
    return out


def membership_plot(path: str, model: AnfisModel) -> str:
    """The membership functions of every input over its training range."""
    plt = _pyplot()
    d = model.n_inputs
    fig, axes = plt.subplots(1, d, figsize=(4.2 * d, 3.4), squeeze=False)
    for i, v in enumerate(model.inputs):
        ax = axes[0, i]
        x = np.linspace(v.min, v.max, 400)
        s = (x - model.scale_offset[i]) / model.scale_span[i]
        c, w = model.centres[i], model.widths[i]
        b = None if model.slopes is None else model.slopes[i]
        for j in range(c.size):
            mu = np.exp(log_membership(model.mf_type, s[:, None], c[j:j + 1], w[j:j + 1],
                                       None if b is None else b[j:j + 1]))[:, 0]
            ax.plot(x, mu, label=f"MF {j + 1}")
        ax.set_xlabel(_label(v.name, v.unit))
        ax.set_ylim(-0.02, 1.05)
        ax.grid(alpha=0.3)
        if i == 0:
            ax.set_ylabel("membership")
    fig.suptitle(f"{model.mf_type} membership functions ({model.n_rules} rules)")
    return _save(fig, plt, path)


def surface_plot(path: str, model: AnfisModel, n: int = 40) -> str:
    """The output over the first two inputs' training ranges (further inputs held at
    the centre of their range, e.g. velocity 0 when the range straddles it)."""
    plt = _pyplot()
    v1 = model.inputs[0]
    v2 = model.inputs[1] if model.n_inputs > 1 else None
    fig = plt.figure(figsize=(7, 5.5))
    ax = fig.add_subplot(111, projection="3d")
    a = np.linspace(v1.min, v1.max, n)
    if v2 is None:
        ax.remove()
        ax = fig.add_subplot(111)
        ax.plot(a, model.predict(a[:, None]))
        ax.set_xlabel(_label(v1.name, v1.unit))
        ax.set_ylabel(_label(model.output.name, model.output.unit))
        return _save(fig, plt, path)
    b = np.linspace(v2.min, v2.max, n)
    A, B = np.meshgrid(a, b)
    X = np.zeros((A.size, model.n_inputs))
    X[:, 0], X[:, 1] = A.ravel(), B.ravel()
    held = []
    for k in range(2, model.n_inputs):
        v = model.inputs[k]
        mid = 0.0 if v.min < 0.0 < v.max else 0.5 * (v.min + v.max)
        X[:, k] = mid
        held.append(f"{v.name} = {mid:g}")
    Z = model.predict(X).reshape(A.shape)
    ax.plot_surface(A, B, Z, cmap="viridis", linewidth=0, antialiased=True)
    ax.set_xlabel(_label(v1.name, v1.unit))
    ax.set_ylabel(_label(v2.name, v2.unit))
    ax.set_zlabel(_label(model.output.name, model.output.unit))
    ax.set_title("fuzzy surface" + (f" at {', '.join(held)}" if held else ""))
    return _save(fig, plt, path)


def training_plot(path: str, curve: dict[str, Sequence[float] | None]) -> str:
    """Training (and validation) RMSE against epoch."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    tr = np.asarray(curve["train_rmse"], dtype=float)
    ax.plot(np.arange(1, tr.size + 1), tr, label="training")
    val = curve.get("val_rmse")
    if val:
        ax.plot(np.arange(1, len(val) + 1), np.asarray(val, dtype=float), label="validation")
    ax.set_xlabel("epoch")
    ax.set_ylabel("RMSE")
    ax.set_yscale("log")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    ax.set_title("hybrid learning")
    return _save(fig, plt, path)


# Any: a matplotlib figure and pyplot, imported lazily (heavy third party)
def _save(fig: Any, plt: Any, path: str) -> str:
    fig.tight_layout()
    save_figure(fig, path, 110)  # whole or not at all (pamd.wire.atomic)
    plt.close(fig)
    return path

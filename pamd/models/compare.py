"""Models judged side by side on the same samples: seed 002's comparison table.

Role: for one or several models of any kind, the extraction settings that give every
model the inputs it was trained on from the same recorded samples (`common_options`),
each model's predictions on them (`predict_samples`, run by run for the stateful
kinds), its metrics (`pamd.models.metrics`) and its tick cost (`tick_cost_us`: the compiled
evaluator timed on the data's own rows), and the table itself (`format_comparison`).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from pamd.models.contract import InverseModel, velocity_window
from pamd.models.data.samples import INPUT_UNITS, OUTPUT_UNITS, ExtractOptions, Samples
from pamd.models.metrics import regression_metrics
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import ModelError

#: Comparison table columns: metric key, header, format (seed 002's Table 4 and more).
COMPARISON_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("n_params", "params", "d"), ("sse", "SSE", ".4g"), ("nrmse_fit_pct", "fit %", ".2f"),
    ("aic", "AIC", ".1f"), ("sbc", "SBC", ".1f"), ("mse", "MSE", ".4g"),
    ("rmse", "RMSE", ".4g"), ("max_deviation_pct", "max dev %", ".2f"),
    ("tick_cost_us", "tick us", ".2f"),
)


@dataclass
class Judged:
    """One model's showing on the samples."""

    file: str
    model: InverseModel
    y_hat: np.ndarray
    clipped: np.ndarray
    metrics: dict[str, float]
    tick_cost_us: float

    def as_json(self) -> JsonObject:
        return {"file": self.file, "kind": self.model.kind, "n_params": self.model.n_params,
                "samples": int(self.y_hat.size),  # what the metrics cover
                "metrics": {k: _json_float(v) for k, v in self.metrics.items()},
                "tick_cost_us": _json_float(self.tick_cost_us),
                "clipped_samples": int(self.clipped.sum())}


def common_options(models: Sequence[InverseModel], muscle: str | None = None,
                   settle_s: float | None = None, rate_hz: float | None = None,
                   actuation: str | None = None) -> ExtractOptions:
    """Extraction settings giving every model its inputs from the same samples (the
    union of their inputs; settle time, rate and the actuation of tables that do not
    say theirs as the first model was trained with unless given; one velocity filter,
    or an error if the models disagree)."""
    names: list[str] = []
    outputs = {m.output.name for m in models}
    if len(outputs) != 1:
        raise ModelError(f"the models have different outputs ({', '.join(sorted(outputs))}); "
                         "compare models of one output")
    output = outputs.pop()
    if output not in OUTPUT_UNITS:
        raise ModelError(f"model output {output!r} is not a recorded signal "
                         f"(known: {', '.join(OUTPUT_UNITS)})")
    windows: set[float] = set()
    for m in models:
        _take_inputs(m, names, windows)
    if len(windows) > 1:
        raise ModelError(f"the models filter their velocity differently ({sorted(windows)} s);"
                         " evaluate them separately")
    ext = (models[0].provenance.get("data") or {}).get("extraction") or {}
    order = [n for n in INPUT_UNITS if n in names]
    return ExtractOptions(
        inputs=tuple(order), output=output, muscle=muscle,
        settle_s=settle_s if settle_s is not None else float(ext.get("settle_s", 2.0)),
        rate_hz=rate_hz if rate_hz is not None else float(ext.get("rate_hz", 50.0)),
        velocity_window_s=windows.pop() if windows else MODEL_VELOCITY_WINDOW_S,
        actuation=actuation if actuation is not None else _str_or_none(ext.get("actuation")))


def _take_inputs(m: InverseModel, names: list[str], windows: set[float]) -> None:
    """Add model `m`'s inputs to `names` (each one a recorded signal) and its velocity
    filter's window, if it has a velocity input, to `windows` (which it must state)."""
    for v in m.inputs:
        if v.name not in INPUT_UNITS:
            raise ModelError(f"model input {v.name} cannot be taken from recordings "
                             f"(known: {', '.join(INPUT_UNITS)})")
        if v.name not in names:
            names.append(v.name)
    if any(v.name == "velocity_mm_s" for v in m.inputs):
        w = velocity_window(m)
        if w is None:
            raise ModelError("the model's velocity_mm_s input does not state its filter "
                             "window (derived_inputs.velocity_mm_s.window_s)")
        windows.add(w)


def _str_or_none(v: object) -> str | None:
    return v if isinstance(v, str) else None


def columns_for(model: InverseModel, samples: Samples) -> np.ndarray:
    """The samples' columns in the model's input order."""
    return samples.X[:, [samples.inputs.index(v.name) for v in model.inputs]]


def predict_samples(model: InverseModel, X: np.ndarray,
                    run: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(y_hat, clipped) on rows X; a stateful model starts afresh on each run."""
    if not model.stateful or run is None:
        return model.predict(X, return_clipped=True)
    y = np.empty(X.shape[0])
    clipped = np.zeros(X.shape[0], dtype=bool)
    for r in np.unique(run):
        sel = run == r
        y[sel], clipped[sel] = model.predict(X[sel], return_clipped=True)
    return y, clipped


def tick_cost_us(model: InverseModel, X: np.ndarray, repeats: int = 5,
                 max_rows: int = 2000) -> float:
    """Microseconds per call of the compiled evaluator on the rows X (best of
    `repeats` passes, so that a busy machine inflates it as little as it can)."""
    ev = model.compile()
    rows = [tuple(map(float, r)) for r in X[:max_rows]]
    if not rows:
        return math.nan
    ev.reset(*rows[0])
    f = ev.evaluate
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for r in rows:
            f(*r)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / len(rows)


def judge(files: Sequence[str], models: Sequence[InverseModel], samples: Samples,
          *, timing: bool = True) -> list[Judged]:
    out = []
    for file, m in zip(files, models, strict=True):
        X = columns_for(m, samples)
        y_hat, clipped = predict_samples(m, X, samples.run)
        metrics = regression_metrics(samples.y, y_hat, m.n_params)
        out.append(Judged(file, m, y_hat, clipped, metrics,
                          tick_cost_us(m, X) if timing else math.nan))
    return out


def format_comparison(rows: Sequence[Judged], out: TextIO | None = None) -> None:
    """One row per model: kind, file and seed 002's figures (plus max deviation and the
    tick cost)."""
    out = out or sys.stdout
    names = [f"{j.model.kind}: {j.file}" for j in rows]
    w = max(24, *(len(n) + 2 for n in names))
    head = f"  {'model':<{w}}" + "".join(f"{h:>11}" for _, h, _ in COMPARISON_COLUMNS)
    print(head, file=out)
    print("  " + "-" * (len(head) - 2), file=out)
    for name, j in zip(names, rows, strict=True):
        vals = {**j.metrics, "n_params": j.model.n_params, "tick_cost_us": j.tick_cost_us}
        cells = []
        for key, _, fmt in COMPARISON_COLUMNS:
            v = vals.get(key)
            bad = v is None or (isinstance(v, float) and not math.isfinite(v))
            cells.append(f"{'-':>11}" if bad else f"{v:>11{fmt}}")
        print(f"  {name:<{w}}" + "".join(cells), file=out)


def _json_float(v: object) -> JsonValue:
    return None if isinstance(v, float) and not math.isfinite(v) else v

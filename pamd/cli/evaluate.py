"""`pamd evaluate MODEL.json DATA...`: judge an inverse model on recorded data the way
the papers do (MSE, RMSE, MAE, max error and deviation %, SSE, NRMSE fit, AIC, SBC,
NDEI) and draw its figures."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Mapping
from typing import Any, TextIO

from pamd.anfis.extraction import load_samples
from pamd.anfis.model import AnfisModel
from pamd.anfis.modelfile import load
from pamd.anfis.samples import INPUT_UNITS, OUTPUT_UNITS, ExtractOptions
from pamd.control.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.errors import ModelError
from pamd.metrics import regression_metrics

#: Table rows: metric key, label, format.
METRIC_ROWS: tuple[tuple[str, str, str], ...] = (
    ("mse", "MSE", ".4g"), ("rmse", "RMSE", ".4g"), ("mae", "MAE", ".4g"),
    ("max_abs_error", "max |error|", ".4g"), ("max_deviation_pct", "max deviation %", ".2f"),
    ("sse", "SSE", ".4g"), ("nrmse_fit_pct", "NRMSE fit %", ".2f"), ("aic", "AIC", ".1f"),
    ("sbc", "SBC", ".1f"), ("ndei", "NDEI", ".4g"),
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate", help="metrics and plots of an inverse model on recorded data",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Evaluate a model file on recorded runs (MCAP or CSV). The samples "
        "are extracted as for training (same filter, same drops; settings from the "
        "model file unless overridden). Inputs outside the model's training ranges are "
        "clipped, counted and shown, never extrapolated.",
        epilog="examples:\n"
        "  pamd evaluate model.json runs/50kg.mcap\n"
        "  pamd evaluate model.json runs/50kg.mcap --json --plot figs/50kg")
    p.add_argument("model", metavar="MODEL.json", help="a model file from pamd train")
    p.add_argument("data", nargs="+", metavar="DATA", help="MCAP recordings or CSV files")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object of the metrics (keys: rmse, mae, ndei, ...)")
    p.add_argument("--plot", metavar="PREFIX", help="write PREFIX_prediction.png, _error.png, "
                   "_membership.png, _surface.png (and _training.png); needs matplotlib")
    p.add_argument("--muscle", help="MCAP: only this muscle (default: every muscle)")
    p.add_argument("--settle-s", type=float, help="drop this long after each start "
                   "(default: as in training)")
    p.add_argument("--rate-hz", type=float, help="decimate to this rate (default: as in "
                   "training)")
    p.set_defaults(func=run)


def extract_options_for(model: AnfisModel, muscle: str | None = None,
                        settle_s: float | None = None,
                        rate_hz: float | None = None) -> ExtractOptions:
    """Extraction settings that reproduce how `model` was trained."""
    names = tuple(v.name for v in model.inputs)
    bad = [n for n in names if n not in INPUT_UNITS]
    if bad:
        raise ModelError(f"model input(s) {', '.join(bad)} cannot be taken from recordings "
                         f"(known: {', '.join(INPUT_UNITS)})")
    if model.output.name not in OUTPUT_UNITS:
        raise ModelError(f"model output {model.output.name!r} is not a recorded signal "
                         f"(known: {', '.join(OUTPUT_UNITS)})")
    ext = (model.provenance.get("data") or {}).get("extraction") or {}
    vel = model.derived_inputs.get("velocity_mm_s") or {}
    if "velocity_mm_s" in names and not isinstance(vel.get("window_s"), (int, float)):
        raise ModelError("the model's velocity_mm_s input does not state its filter window "
                         "(derived_inputs.velocity_mm_s.window_s)")
    return ExtractOptions(
        inputs=names, output=model.output.name, muscle=muscle,
        settle_s=settle_s if settle_s is not None else float(ext.get("settle_s", 2.0)),
        rate_hz=rate_hz if rate_hz is not None else float(ext.get("rate_hz", 50.0)),
        velocity_window_s=float(vel.get("window_s", MODEL_VELOCITY_WINDOW_S)))


def format_table(rows: Mapping[str, Mapping[str, float]], unit: str = "",
                 out: TextIO | None = None) -> None:
    """The metrics table: one column per data set (train, validation, test, ...)."""
    out = out or sys.stdout
    sets = list(rows)
    width = max(12, *(len(s) + 2 for s in sets))
    head = f"  {'metric':<18}" + "".join(f"{s:>{width}}" for s in sets)
    print(head, file=out)
    print("  " + "-" * (len(head) - 2), file=out)
    for key, label, fmt in METRIC_ROWS:
        cells = []
        for s in sets:
            v = rows[s].get(key)
            cells.append(f"{'-':>{width}}" if v is None or (isinstance(v, float) and
                                                           math.isnan(v))
                         else f"{v:>{width}{fmt}}")
        print(f"  {label:<18}" + "".join(cells), file=out)
    if unit:
        print(f"  (errors in {unit}, squared errors in {unit}^2)", file=out)


def run(args: argparse.Namespace) -> int:
    model = load(args.model)
    opts = extract_options_for(model, args.muscle, args.settle_s, args.rate_hz)
    samples = load_samples(args.data, opts)
    y_hat, clipped = model.predict(samples.X, return_clipped=True)
    metrics = regression_metrics(samples.y, y_hat, model.n_params)
    n_clip = int(clipped.sum())
    note = (f"{len(samples)} samples from {len(samples.runs)} run(s); {n_clip} "
            f"({100.0 * n_clip / len(samples):.1f} %) had inputs outside the training "
            "ranges (clipped)")
    if args.json:
        print(json.dumps({k: _json_float(v) for k, v in metrics.items()}, indent=2))
        print(f"pamd evaluate: {note}", file=sys.stderr)
    else:
        print(f"{args.model}: {model!r}")
        print(f"  {note}")
        format_table({"evaluation": metrics}, model.output.unit)
    if args.plot:
        from pamd.anfis.plots import write_plots

        paths = write_plots(args.plot, model, samples.time_axis(), samples.y, y_hat, clipped,
                            title=f"{model.output.name}: {', '.join(args.data)[:80]}")
        print(f"plots: {', '.join(paths)}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _json_float(v: Any) -> Any:
    return None if isinstance(v, float) and not math.isfinite(v) else v

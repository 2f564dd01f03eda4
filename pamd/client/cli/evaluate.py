"""`pamd evaluate MODEL... DATA...`: judge one or several inverse models (any kind) on
the same recorded data the way the papers do (MSE, RMSE, MAE, max error and
deviation %, SSE, NRMSE fit, AIC, SBC, NDEI, and each model's tick cost), side by
side in seed 002's comparison table, and draw their figures."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Mapping, Sequence
from typing import TextIO

import numpy as np

from pamd.client.judging import TickReport, judge_as_tick
from pamd.client.recording import recording_files
from pamd.client.training_tables import load_samples
from pamd.config.schema import ACTUATIONS
from pamd.models.anfis.anfis_plots import require_matplotlib
from pamd.models.compare import Judged, common_options, format_comparison
from pamd.models.contract import InverseModel
from pamd.models.data.samples import Samples
from pamd.models.data.splitting import resplit
from pamd.models.plots import write_overlay
from pamd.models.registry import KINDS, load_model
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import ModelError

#: Table rows: metric key, label, format.
METRIC_ROWS: tuple[tuple[str, str, str], ...] = (
    ("mse", "MSE", ".4g"), ("half_mse", "MSE/2 (seed 001)", ".4g"), ("rmse", "RMSE", ".4g"),
    ("mae", "MAE", ".4g"),
    ("max_abs_error", "max |error|", ".4g"), ("max_deviation_pct", "max deviation %", ".2f"),
    ("sse", "SSE", ".4g"), ("nrmse_fit_pct", "NRMSE fit %", ".2f"), ("aic", "AIC", ".1f"),
    ("sbc", "SBC", ".1f"), ("ndei", "NDEI", ".4g"),
)
MODEL_SUFFIX = ".json"
#: `--held-out`: the set the metrics cover.
HELD_OUT: tuple[str, ...] = ("all", "validation", "test")


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "evaluate", help="metrics and plots of inverse models on recorded data",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Evaluate one or several model files (any kind: "
        f"{', '.join(KINDS)}) on recorded runs (MCAP or CSV). Arguments "
        "ending in .json are models, the rest data. The samples are extracted once, as "
        "for training (same filter, same drops; settings from the first model file "
        "unless overridden), and every model is judged on the same samples. Inputs "
        "outside a model's training ranges are clipped, counted and shown, never "
        "extrapolated. With several models: seed 002's comparison table (parameters, "
        "SSE, NRMSE fit, AIC, SBC, MSE, RMSE, max deviation, tick cost in us per "
        "sample of the compiled evaluator) and overlaid plots.",
        epilog="examples:\n"
        "  pamd evaluate model.json runs/50kg.mcap\n"
        "  pamd evaluate model.json runs/50kg.mcap --json --plot figs/50kg\n"
        "  pamd evaluate model.json runs/track          # every recording in a directory\n"
        "  pamd evaluate anfis.json tsf.json sarosi.json runs/50kg.mcap --plot figs/cmp")
    p.add_argument("files", nargs="+", metavar="MODEL.json... DATA...",
                   help="model files (.json) then MCAP recordings, CSV files or directories "
                   "(a collection, or a --record directory)")
    p.add_argument("--json", action="store_true",
                   help='print one JSON object: {"models": [{"file", "kind", "n_params", '
                   '"samples", "metrics": {...}}, ...]} (samples: how many the metrics '
                   "cover; with one model also its metrics and samples at the top level: "
                   "rmse, mae, ndei, ...)")
    p.add_argument("--plot", metavar="PREFIX", help="write PREFIX_prediction.png and "
                   "_error.png (models overlaid); with one model of a kind that draws more ("
                   + ", ".join(k.name for k in KINDS.values() if k.plots is not None)
                   + ") also its own figures (ANFIS structure: _membership.png, "
                   "_surface.png and _training.png); needs matplotlib")
    p.add_argument("--muscle", help="MCAP: only this muscle (default: every muscle)")
    p.add_argument("--settle-s", type=float, help="drop this long after each start "
                   "(default: as in training)")
    p.add_argument("--rate-hz", type=float, help="decimate to this rate (default: as in "
                   "training)")
    add_actuation_option(p, "default: as the first model was trained with, else "
                         "proportional")
    p.add_argument("--held-out", choices=HELD_OUT, default=None,
                   help="the set the metrics cover: all (every sample of DATA: training, "
                   "validation and test alike; the basis of seed 002's AIC and SBC and of "
                   "the papers' in-sample figures), or only the validation or the test part "
                   "the models' training held out, found again in DATA as their files say "
                   "(pamd train --split-by block, run or random: the split's settings; "
                   "--split-by curve: the held-out pressure curves); DATA must be what they "
                   "were trained on, and the models must have held out the same part. "
                   "Default: every sample of DATA, which need not be training data; --json "
                   "says per model how many samples the metrics cover (samples)")
    p.add_argument("--no-timing", action="store_true", help="skip the tick-cost measurement")
    p.set_defaults(func=run)


def add_actuation_option(p: argparse.ArgumentParser, default: str) -> None:
    """`--actuation`, for data tables that do not say their rig's valves."""
    p.add_argument("--actuation", choices=ACTUATIONS, help="the muscle's valves where a "
                   "data file does not say (a lab's own CSV or MAT table; pamd's recordings "
                   "and exports carry their config, which wins): onoff keeps the samples "
                   "the exhaust valve's PWM pulses flag, as the control's own work, where a "
                   f"proportional regulator's open exhaust valve drops them ({default})")


def say_own_actuations(samples: Samples, command: str) -> None:
    """One line per run whose file's config overrode the `actuation` option."""
    given = samples.options.actuation
    for r in samples.runs:
        if given is not None and r.get("actuation") != given:
            print(f"{command}: {r['source']} [{r['muscle']}]: its config says actuation: "
                  f"{r.get('actuation')}, kept (the option applies to tables that do not "
                  "say)", file=sys.stderr)


def split_files(files: Sequence[str]) -> tuple[list[str], list[str]]:
    """(model files, data files): the leading .json arguments are the models."""
    models = [f for f in files if f.lower().endswith(MODEL_SUFFIX)]
    data = [f for f in files if not f.lower().endswith(MODEL_SUFFIX)]
    if not models:
        raise ModelError("no model file: give MODEL.json first, then the data")
    if not data:
        raise ModelError("no data: give the MCAP recordings or CSV files after the models")
    return models, data


def data_files(paths: Sequence[str]) -> list[str]:
    """The data files `paths` name: a file as given; a directory as `pamd inspect`, `plot`
    and `export` read it (a collection: its manifest's step files, in order, not the
    collection's own load-change recording; a `--record` directory: its .mcap files)."""
    out: list[str] = []
    for p in paths:
        out += [f for f, _, _ in recording_files(p)] if os.path.isdir(p) else [p]
    return out


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
    files, data = split_files(args.files)
    if args.plot:
        require_matplotlib()  # before the models are read and judged, not after
    models = [load_model(f) for f in files]
    opts = common_options(models, args.muscle, args.settle_s, args.rate_hz, args.actuation)
    samples = load_samples(data, opts)  # recordings and tables (CSV, MAT)
    say_own_actuations(samples, "pamd evaluate")
    if args.held_out:
        samples = held_out_part(samples, files, models, args.held_out)
    pairs = judge_as_tick(files, models, samples, timing=not args.no_timing)  # as the tick
    judged = [j for j, _ in pairs]
    note = f"{len(samples)} samples from {len(samples.runs)} run(s)"
    clip_notes = [f"{j.file}: {int(j.clipped.sum())} "
                  f"({100.0 * j.clipped.sum() / len(samples):.1f} %) clipped" for j in judged]
    forward = {j.file: _forward(j.model, samples) for j in judged}
    if args.json:
        _print_json(pairs, len(samples), forward)
        print(f"pamd evaluate: {note}; " + "; ".join(clip_notes), file=sys.stderr)
    elif len(judged) == 1:
        _print_one(judged[0], len(samples), note, forward[judged[0].file])
    else:
        _print_many(judged, f"{note} ({', '.join(data)[:100]})", clip_notes)
    for j, r in pairs:
        print(f"  {j.file}: {r.summary()}", file=sys.stderr if args.json else sys.stdout)
        for w in r.warnings(j.file):
            print(f"pamd evaluate: {w}", file=sys.stderr)
    if args.plot:
        paths = _plots(args.plot, judged, samples, ", ".join(data)[:80])
        print(f"plots: {', '.join(paths)}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _print_json(pairs: list[tuple[Judged, TickReport]], n_samples: int,
                forward: dict[str, dict[str, dict[str, float]]]) -> None:
    """The judgement as one JSON document: one model's metrics at its top, and each
    model's, as the tick runs it and by its forward models."""
    doc: JsonObject = {}
    if len(pairs) == 1:
        doc.update({k: _json_float(v) for k, v in pairs[0][0].metrics.items()})
        doc["samples"] = n_samples
    doc["models"] = [{**j.as_json(), "tick": r.as_json(),
                      **({"forward": {k: {m: _json_float(v) for m, v in t.items()}
                                      for k, t in forward[j.file].items()}}
                         if forward[j.file] else {})} for j, r in pairs]
    print(json.dumps(doc, indent=2))


def _print_many(judged: list[Judged], what: str, clip_notes: list[str]) -> None:
    """Several models' judgements side by side on the same samples (`what`), with each
    one's clipped share."""
    print(f"{len(judged)} models on the same {what}:")
    format_comparison(judged)
    unit = judged[0].model.output.unit
    print(f"  (errors in {unit}; max dev % of the measured range; fit % = NRMSE fit; "
          "tick us = compiled evaluator per sample on this machine)")
    for c in clip_notes:
        print(f"  {c}")


def _print_one(j: Judged, n_samples: int, note: str,
               forward: dict[str, dict[str, float]]) -> None:
    """One model's judgement as a table, its clipped share, its tick cost and its
    forward models."""
    print(f"{j.file}: {j.model!r}")
    print(f"  {note}; {int(j.clipped.sum())} ({100.0 * j.clipped.sum() / n_samples:.1f}"
          " %) had inputs outside the training ranges or an output held (clipped)")
    format_table({"evaluation": j.metrics}, j.model.output.unit)
    print(f"  tick cost of the compiled model: {j.tick_cost_us:.2f} us per sample")
    if forward:
        print("  forward models against the measured length (seed 003's MAE, RMSE):")
        format_table(forward, "mm")


def held_out_part(samples: Samples, files: Sequence[str], models: Sequence[InverseModel],
                  part: str) -> Samples:
    """The samples `--held-out` names: all of them, or the part (validation, test) the
    models' training held out: whole pressure curves where they were split by curve,
    else the parts their split settings give again on these samples."""
    if part == "all":
        print(f"pamd evaluate: judging all {len(samples)} samples (training, validation "
              "and test alike: in-sample figures where DATA is the training data)",
              file=sys.stderr)
        return samples
    bys = {_split_of(m).get("by") for m in models}
    if bys == {"curve"}:
        return held_out_curves(samples, files, models, part)
    if len(bys) > 1:
        raise ModelError(f"--held-out {part}: the models were split differently "
                         f"({', '.join(sorted(str(b) for b in bys))}); judge them separately")
    mask: np.ndarray | None = None
    for f, m in zip(files, models, strict=True):
        parts = resplit(samples, _split_of(m), f)
        this = parts.in_validation if part == "validation" else parts.in_test
        if this is None or not this.any():
            flag = "--test-split" if part == "test" else "--val-split"
            raise ModelError(f"--held-out {part}: {f} held out no {part} part (train it "
                             f"with {flag} above 0)")
        if mask is not None and not np.array_equal(mask, this):
            raise ModelError(f"--held-out {part}: {f} held out other samples than the first "
                             "model; judge such models separately")
        mask = this
    assert mask is not None
    how = _split_of(models[0])
    print(f"pamd evaluate: judging the held-out {part} part ({int(mask.sum())} of "
          f"{len(samples)} samples; split by {how.get('by')}, seed {how.get('seed')})",
          file=sys.stderr)
    return samples.subset(mask)


def _split_of(model: InverseModel) -> dict[str, object]:
    how = model.provenance.get("split")
    return how if isinstance(how, dict) else {}


def held_out_curves(samples: Samples, files: Sequence[str], models: Sequence[InverseModel],
                    part: str) -> Samples:
    """The samples on the pressure curves every model's training held out as `part`."""
    key = f"{part}_curves_bar"
    held: list[float] | None = None
    for f, m in zip(files, models, strict=True):
        how = m.provenance.get("split") or {}
        curves = how.get(key) if isinstance(how, dict) else None
        if not isinstance(curves, list) or not curves:
            flag = "--test-split" if part == "test" else "--val-split"
            raise ModelError(f"--held-out {part}: {f} lists no held-out {part} curves (train "
                             f"it with --split-by curve and {flag} above 0)")
        if held is not None and sorted(curves) != held:
            raise ModelError(f"--held-out {part}: {f} held out {sorted(curves)} bar, the "
                             f"first model {held} bar; judge such models separately")
        held = sorted(float(c) for c in curves)
    if "pressure_bar" in samples.inputs:
        p = samples.X[:, samples.inputs.index("pressure_bar")]
    elif samples.output == "pressure_bar":
        p = samples.y
    else:
        raise ModelError("--held-out: the samples have no pressure_bar to find the curves by")
    mask = np.isin(np.round(p, 6), np.round(np.array(held or []), 6))
    if not mask.any():
        raise ModelError(f"--held-out {part}: no sample of the data lies on the held-out "
                         f"curves {held} bar; give the map the models were trained on")
    print(f"pamd evaluate: judging the held-out {part} curves {held} bar "
          f"({int(mask.sum())} of {len(samples)} samples)", file=sys.stderr)
    return samples.subset(mask)


def _plots(prefix: str, judged: list[Judged], samples: Samples, what: str) -> list[str]:
    j = judged[0]
    plots = KINDS[j.model.kind].plots if j.model.kind in KINDS else None
    if len(judged) == 1 and plots is not None:
        return plots(prefix, j.model, samples.time_axis(), samples.y, j.y_hat, j.clipped,
                     f"{j.model.output.name}: {what}")

    return write_overlay(prefix, judged, samples.time_axis(), samples.y,
                         title=f"{judged[0].model.output.name}: {what}")


def _forward(model: object, samples: Samples) -> dict[str, dict[str, float]]:
    """A kind with a forward model of the length (fn-qupi: FN-QUPI and QUPI alone) scored
    against the measured length over whole runs in time order, at each run's load; {}
    for the other kinds."""
    score = getattr(model, "forward_metrics", None)
    if score is None or "length_mm" not in samples.inputs:
        return {}
    col = samples.inputs.index("length_mm")
    out: dict[str, dict[str, float]] = score(samples.X[:, col], samples.y, samples.run,
                                             [r.get("load_kg") for r in samples.runs])
    return out


def _json_float(v: object) -> JsonValue:
    return None if isinstance(v, float) and not math.isfinite(v) else v

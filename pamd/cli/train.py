"""`pamd train DATA... --out MODEL.json`: train the ANFIS inverse model (force, length
[, velocity] -> pressure) from recorded runs, with a progress bar and a final
metrics table."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from pamd.anfis.extraction import derived_inputs, load_samples
from pamd.anfis.modelfile import save
from pamd.anfis.samples import INPUT_UNITS, OUTPUT_UNITS, ExtractOptions
from pamd.anfis.splitting import split
from pamd.anfis.training import TrainingOptions, fit
from pamd.cli.evaluate import format_table
from pamd.control.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.errors import ModelError
from pamd.metrics import regression_metrics


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "train", help="train the ANFIS inverse model from recorded runs",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Train a first-order Sugeno ANFIS (hybrid learning) that maps the "
        "muscle's force and length (and optionally its velocity) to the pressure that "
        "produced them, from MCAP recordings (pamd run --record) or CSV files with named "
        "columns. Faults, limit-flagged samples, idle stretches, lead-in ramps and the "
        "first --settle-s of each run are dropped; the rest is decimated to --rate-hz and "
        "split into training / validation (/ test) sets by whole time blocks or runs.",
        epilog="examples:\n"
        "  pamd train runs/*.mcap --out model.json\n"
        "  pamd train runs/*.mcap --out model3.json --inputs force_n,length_mm,"
        "velocity_mm_s --mfs 3\n"
        "  pamd train lab_export.csv --out model.json --val-split 0 --epochs 50")
    p.add_argument("data", nargs="+", metavar="DATA", help="MCAP recordings or CSV files")
    p.add_argument("--out", required=True, metavar="MODEL.json", help="model file to write")
    p.add_argument("--inputs", default="force_n,length_mm",
                   help=f"comma-separated model inputs from {', '.join(INPUT_UNITS)} "
                   "(default force_n,length_mm)")
    p.add_argument("--output", default="pressure_bar", choices=sorted(OUTPUT_UNITS),
                   help="model output (default pressure_bar)")
    p.add_argument("--mfs", default=None, help="membership functions per input: one number "
                   "or one per input (e.g. 5,5,3); default 5 for two inputs, 3 for three "
                   "(the seeds' layouts: 25 and 27 rules)")
    p.add_argument("--mf-type", choices=("gaussian", "bell"), default="gaussian")
    p.add_argument("--epochs", type=int, default=100, help="training epochs (default 100)")
    p.add_argument("--step", type=float, default=0.01, help="initial step size of the "
                   "premise gradient descent (default 0.01)")
    p.add_argument("--val-split", type=float, default=0.2, metavar="FRACTION",
                   help="share of the data held out for validation (the best epoch on it is "
                   "kept); 0 trains on all DATA (default 0.2)")
    p.add_argument("--test-split", type=float, default=0.0, metavar="FRACTION",
                   help="share held out as a test set, reported and never trained on "
                   "(default 0: test with pamd evaluate on other runs)")
    p.add_argument("--split-by", choices=("block", "run"), default="block",
                   help="hold out whole time blocks (default) or whole runs")
    p.add_argument("--block-s", type=float, default=10.0, help="block length for "
                   "--split-by block (default 10 s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the split (default 0)")
    p.add_argument("--muscle", help="MCAP: only this muscle (default: every muscle)")
    p.add_argument("--settle-s", type=float, default=2.0, help="drop this long after each "
                   "run start, state change and lead-in (default 2 s)")
    p.add_argument("--rate-hz", type=float, default=50.0, help="decimate to this rate "
                   "(default 50 Hz)")
    p.add_argument("--velocity-window-s", type=float, default=MODEL_VELOCITY_WINDOW_S,
                   help="time constant of the velocity input's filter, stored in the model "
                   f"and used by the tick (default {MODEL_VELOCITY_WINDOW_S:g} s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def parse_mfs(text: str | None, n_inputs: int) -> int | list[int]:
    if text is None:
        return 5 if n_inputs <= 2 else 3
    try:
        vals = [int(v) for v in text.split(",")]
    except ValueError:
        raise ModelError(f"--mfs {text!r}: give a whole number or one per input, e.g. "
                         "5,5,3") from None
    if any(v < 1 for v in vals):
        raise ModelError(f"--mfs {text!r}: every input needs at least one membership function")
    if len(vals) == 1:
        return vals[0]
    if len(vals) != n_inputs:
        raise ModelError(f"--mfs {text!r}: {len(vals)} numbers for {n_inputs} inputs")
    return vals


def run(args: argparse.Namespace) -> int:
    inputs = tuple(s.strip() for s in args.inputs.split(",") if s.strip())
    opts = ExtractOptions(inputs=inputs, output=args.output, muscle=args.muscle,
                          settle_s=args.settle_s, rate_hz=args.rate_hz,
                          velocity_window_s=args.velocity_window_s)
    n_mfs = parse_mfs(args.mfs, len(inputs))
    if args.epochs < 1:
        raise ModelError("--epochs must be at least 1")
    samples = load_samples(args.data, opts)
    parts = split(samples, args.val_split, args.test_split, by=args.split_by,
                  block_s=args.block_s, seed=args.seed)
    tr, va, te = parts.train, parts.validation, parts.test
    print(f"pamd train: {len(samples)} samples from {len(samples.runs)} run(s) "
          f"({', '.join(inputs)} -> {args.output}); training {len(tr)}, validation "
          f"{len(va) if va else 0}, test {len(te) if te else 0} (split by {args.split_by})",
          file=sys.stderr)
    topts = TrainingOptions(n_mfs=n_mfs, mf_type=args.mf_type, epochs=args.epochs,
                            initial_step=args.step, seed=args.seed)
    bar = _progress(args.epochs, args.quiet)

    def progress(epoch: int, rmse: float, val: float | None) -> None:
        if bar is not None:
            bar.update(1)
            post = f"train RMSE {rmse:.4g}" + (f", val RMSE {val:.4g}" if val is not None
                                               else "")
            bar.set_postfix_str(post, refresh=False)

    prov: dict[str, Any] = {"data": samples.provenance(), "split": parts.how}
    try:
        result = fit(tr.X, tr.y, topts, input_names=list(inputs),
                     input_units=tr.input_units, output_name=args.output,
                     output_unit=tr.output_unit,
                     validation=(va.X, va.y) if va is not None else None,
                     callback=progress,
                     derived_inputs=derived_inputs(inputs, args.velocity_window_s),
                     provenance=prov)
    finally:
        if bar is not None:
            bar.close()
    model = result.model
    model.provenance["training_curve"] = {
        "train_rmse": result.train_rmse.tolist(),
        "val_rmse": None if result.val_rmse is None else result.val_rmse.tolist()}
    rows = {"train": model.metrics["train"]}
    if "validation" in model.metrics:
        rows["validation"] = model.metrics["validation"]
    if te is not None:
        model.metrics["test"] = regression_metrics(te.y, model.predict(te.X), model.n_params)
        rows["test"] = model.metrics["test"]
    d = os.path.dirname(os.path.abspath(args.out))
    if not os.path.isdir(d):
        raise ModelError(f"--out {args.out}: directory {d} does not exist")
    save(model, args.out)
    print(f"{args.out}: {model!r}, {model.n_params} parameters; best epoch "
          f"{result.best_epoch} of {result.train_rmse.size} (on {result.selected_on}), "
          f"{result.seconds:.2f} s")
    format_table(rows, model.output.unit)
    return 0


def _progress(total: int, quiet: bool) -> Any:
    if quiet:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc="training", unit="epoch", file=sys.stderr,
                dynamic_ncols=True, leave=True)

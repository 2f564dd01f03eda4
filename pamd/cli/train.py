"""`pamd train DATA... --out MODEL.json [--kind KIND]`: train an inverse model (force,
length[, velocity] -> pressure; ANFIS by default, or any kind of `pamd.models`) from
recorded runs, with a progress bar and a final metrics table."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from pamd.cli.evaluate import format_table
from pamd.errors import ModelError
from pamd.metrics import regression_metrics
from pamd.models.anfis.extraction import derived_inputs
from pamd.models.anfis.samples import INPUT_UNITS, OUTPUT_UNITS, ExtractOptions, Samples
from pamd.models.anfis.splitting import Split, split
from pamd.models.anfis.training import TrainingOptions, fit, width_starts
from pamd.models.compare import predict_samples
from pamd.models.registry import KINDS, save_model
from pamd.models.training import DEFAULT_INPUTS, KindOptions, fit_split, rows_of
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.view.judging import coverage, poor_fit
from pamd.view.tables import load_samples


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "train", help="train an inverse model (ANFIS or another kind) from recorded runs",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Train an inverse model (by default a first-order Sugeno ANFIS, "
        "hybrid learning) that maps the muscle's force and length (and optionally its "
        "velocity) to the pressure that produced them, from MCAP recordings (pamd run "
        "--record) or CSV files with named "
        "columns. Faults, limit-flagged samples, idle stretches, lead-in ramps and the "
        "first --settle-s of each run are dropped; the rest is decimated to --rate-hz and "
        "split into training / validation (/ test) sets by whole time blocks or runs.\n\n"
        "--kind picks the model (the seeds' models; default anfis):\n"
        + "".join(f"  {k.name:<11} seed {k.seed}: {k.summary}\n" for k in KINDS.values()),
        epilog="examples:\n"
        "  pamd train runs/sweep --out model.json             # a collection (pamd collect)\n"
        "  pamd train runs/sweep runs/half --out model.json --inputs force_n,length_mm,"
        "velocity_mm_s\n"
        "  pamd train runs/*.mcap --out model.json\n"
        "  pamd train runs/*.mcap --out model3.json --inputs force_n,length_mm,"
        "velocity_mm_s --mfs 3\n"
        "  pamd train lab_export.csv --out model.json --val-split 0 --epochs 50\n"
        "  pamd train runs/*.mcap --out tsf.json --kind ts-fuzzy --tuner mga --epochs 60\n"
        "  pamd train runs/*.mcap --out sarosi.json --kind sarosi")
    p.add_argument("data", nargs="+", metavar="DATA",
                   help="MCAP recordings, CSV files or directories: a collection (pamd "
                   "collect; its steps' files, as the manifest lists them) or a directory of "
                   "recordings (pamd run --record)")
    p.add_argument("--out", required=True, metavar="MODEL.json", help="model file to write")
    p.add_argument("--kind", default="anfis", choices=list(KINDS),
                   help="model kind (default anfis; see above)")
    p.add_argument("--inputs", default=None,
                   help=f"comma-separated model inputs from {', '.join(INPUT_UNITS)} "
                   "(default per kind: " + "; ".join(
                       f"{k} {','.join(v)}" for k, v in DEFAULT_INPUTS.items()) + ")")
    p.add_argument("--output", default="pressure_bar", choices=sorted(OUTPUT_UNITS),
                   help="model output (default pressure_bar)")
    p.add_argument("--mfs", default=None, help="membership functions per input: one number "
                   "or one per input (e.g. 5,5,3); default 5 for two inputs, 3 for three "
                   "(the seeds' layouts: 25 and 27 rules)")
    p.add_argument("--mf-type", choices=("gaussian", "bell"), default="gaussian")
    p.add_argument("--epochs", type=int, default=None, help="training epochs (anfis, "
                   "ts-fuzzy gd; default 100), generations (ts-fuzzy ga/mga; default 60) or "
                   "iterations (mlp; default 500)")
    p.add_argument("--tuner", choices=("gd", "ga", "mga"), default="mga",
                   help="ts-fuzzy: how the premises are tuned (gradient descent, genetic "
                   "algorithm, modified GA; default mga)")
    p.add_argument("--population", type=int, default=100,
                   help="ts-fuzzy ga/mga: strings per generation (default 100)")
    p.add_argument("--hidden", type=int, default=8,
                   help="mlp: tanh neurons in the hidden layer (default 8, seed 001's ANN)")
    p.add_argument("--svr-c", type=float, default=10.0, help="svr: regularisation C "
                   "(default 10)")
    p.add_argument("--svr-epsilon", type=float, default=0.02, help="svr: epsilon tube in "
                   "bar (default 0.02; wider gives fewer support vectors)")
    p.add_argument("--operators", type=int, default=10,
                   help="qupi: play operators per branch, Na = Nb (default 10, seed 003; "
                   "the tick evaluates Na x Nb of them)")
    p.add_argument("--ridge", type=float, default=0.01,
                   help="ts-fuzzy: ridge on the consequents' least squares, scaled units "
                   "(default 0.01; 0 = plain SVD; choose it on the validation split)")
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
    p.add_argument("--seed", type=int, default=0, help="seed of the split and of the "
                   "kind's random choices (GA, MLP initialisation; default 0)")
    p.add_argument("--muscle", help="MCAP: only this muscle (default: every muscle)")
    p.add_argument("--settle-s", type=float, default=2.0, help="drop this long after each "
                   "run start, state change and lead-in (default 2 s)")
    p.add_argument("--rate-hz", type=float, default=50.0, help="decimate to this rate "
                   "(default 50 Hz)")
    p.add_argument("--velocity-window-s", type=float, default=MODEL_VELOCITY_WINDOW_S,
                   help="time constant of the velocity input's filter, stored in the model "
                   f"and used by the tick (default {MODEL_VELOCITY_WINDOW_S:g} s)")
    p.add_argument("--allow-poor-fit", action="store_true", help="write the model even if "
                   "it fits worse than a constant (NRMSE fit <= 0 %% on the validation set; "
                   "refused by default)")
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
    text = args.inputs if args.inputs is not None else ",".join(DEFAULT_INPUTS[args.kind])
    inputs = tuple(s.strip() for s in text.split(",") if s.strip())
    opts = ExtractOptions(inputs=inputs, output=args.output, muscle=args.muscle,
                          settle_s=args.settle_s, rate_hz=args.rate_hz,
                          velocity_window_s=args.velocity_window_s)
    n_mfs = parse_mfs(args.mfs, len(inputs))
    if args.epochs is not None and args.epochs < 1:
        raise ModelError("--epochs must be at least 1")
    d = os.path.dirname(os.path.abspath(args.out))
    if not os.path.isdir(d):
        raise ModelError(f"--out {args.out}: directory {d} does not exist")
    samples = load_samples(args.data, opts)  # recordings and tables (CSV, MAT)
    parts = split(samples, args.val_split, args.test_split, by=args.split_by,
                  block_s=args.block_s, seed=args.seed)
    tr, va, te = parts.train, parts.validation, parts.test
    print(f"pamd train: {len(samples)} samples from {len(samples.runs)} run(s) "
          f"({', '.join(inputs)} -> {args.output}); training {len(tr)}, validation "
          f"{len(va) if va else 0}, test {len(te) if te else 0} (split by {args.split_by})",
          file=sys.stderr)
    if args.kind != "anfis":
        return _run_kind(args, inputs, samples, parts)
    args.epochs = args.epochs or 100
    topts = TrainingOptions(n_mfs=n_mfs, mf_type=args.mf_type, epochs=args.epochs,
                            initial_step=args.step, seed=args.seed)
    bar = _progress(args.epochs * len(width_starts(topts)), args.quiet)  # one run per start

    def progress(epoch: int, rmse: float, val: float | None) -> None:
        if bar is not None:
            bar.update(1)
            post = f"train RMSE {rmse:.4g}" + (f", val RMSE {val:.4g}" if val is not None
                                               else "")
            bar.set_postfix_str(post, refresh=False)

    prov: dict[str, Any] = {"data": samples.provenance(), "split": parts.how,
                            "coverage": coverage(tr.X, inputs)}  # where the data lay
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
    _refuse_poor_fit(model.metrics, args)
    save_model(model, args.out)
    print(f"{args.out}: {model!r}, {model.n_params} parameters; best epoch "
          f"{result.best_epoch} of {result.train_rmse.size} (on {result.selected_on}), "
          f"initial MF width {model.provenance['training']['width_starts']['kept']:g} of "
          f"{len(width_starts(topts))} start(s), {result.seconds:.2f} s")
    format_table(rows, model.output.unit)
    return 0


def _run_kind(args: argparse.Namespace, inputs: tuple[str, ...], samples: Samples,
              parts: Split) -> int:
    """Every kind but anfis: `pamd.models.training.fit_kind`, then the same report."""
    te = parts.test
    default_epochs = {"ts-fuzzy": 100 if args.tuner == "gd" else 60, "mlp": 500}
    epochs = args.epochs or default_epochs.get(args.kind, 1)
    kopts = KindOptions(epochs=epochs, seed=args.seed, tuner=args.tuner,
                        population=args.population, ridge=args.ridge,
                        hidden=args.hidden, operators=args.operators, svr_c=args.svr_c,
                        svr_epsilon=args.svr_epsilon,
                        n_mfs=None if args.mfs is None else parse_mfs(args.mfs, len(inputs)))
    iterative = args.kind == "ts-fuzzy"
    bar = _progress(epochs, args.quiet, "generation" if args.tuner != "gd" else "epoch"
                    ) if iterative else None

    def progress(step: int, err: float, val: float | None) -> None:
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"train MSE {err:.4g}", refresh=False)

    prov: dict[str, Any] = {"data": samples.provenance(), "split": parts.how,
                            "coverage": coverage(parts.train.X, inputs)}
    try:
        model = fit_split(args.kind, samples, parts, opts=kopts,
                          derived_inputs=derived_inputs(inputs, args.velocity_window_s),
                          provenance=prov, callback=progress)
    finally:
        if bar is not None:
            bar.close()
    rows: dict[str, dict[str, float]] = {
        k: model.metrics[k] for k in ("train", "validation") if k in model.metrics}
    if te is not None:
        if model.stateful:  # over whole runs, scored on the test rows

            y_all, _ = predict_samples(model, samples.X, samples.run)
            y_hat = y_all[rows_of(samples, te)]
        else:
            y_hat = model.predict(te.X)
        model.metrics["test"] = regression_metrics(te.y, y_hat, model.n_params)
        rows["test"] = model.metrics["test"]
    _refuse_poor_fit(model.metrics, args)
    save_model(model, args.out)
    print(f"{args.out}: {model.kind} model {model!r}, {model.n_params} parameters")
    format_table(rows, model.output.unit)
    fwd = {k[len("forward_"):]: v for k, v in model.metrics.items() if k.startswith("forward_")}
    if fwd:
        qupi = model.kind == "qupi"
        print("  forward model (" + ("length from the pressure history" if qupi else
                                     "force from pressure and contraction") + "):")
        format_table(fwd, "mm" if qupi else "N")
    return 0


def _refuse_poor_fit(metrics: dict[str, Any], args: argparse.Namespace) -> None:
    why = poor_fit(metrics)
    if why is not None and not args.allow_poor_fit:
        raise ModelError(f"{args.out} not written: {why}; check the inputs, the data and the "
                         "layout, or write it anyway with --allow-poor-fit")
    if why is not None:
        print(f"pamd train: WARNING: {why}; written anyway (--allow-poor-fit)",
              file=sys.stderr)


def _progress(total: int, quiet: bool, unit: str = "epoch") -> Any:
    if quiet:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc="training", unit=unit, file=sys.stderr,
                dynamic_ncols=True, leave=True)

"""`pamd train DATA... --out MODEL.json [--kind KIND] [--target SIGNAL]`: train an inverse
model (force, length[, velocity] -> pressure; ANFIS by default, or any kind of
`pamd.models`) or, with `--target force_n --inputs pressure_bar,contraction`, a forward
force model (seed 002's F(p, k)), from recorded runs or tables: a progress bar for each
phase (reading, each training start; `pamd.client.cli.progress`), then the model's line with the
wall time it took and a final metrics table."""

from __future__ import annotations

import argparse
import os
import sys
import time

from pamd.client.cli import progress
from pamd.client.cli.evaluate import add_actuation_option, format_table, say_own_actuations
from pamd.client.judging import poor_fit
from pamd.client.training_tables import data_files, load_samples
from pamd.models.compare import predict_samples
from pamd.models.contract import InverseModel
from pamd.models.data.extraction import derived_inputs
from pamd.models.data.samples import INPUT_UNITS, OUTPUT_UNITS, ExtractOptions, Samples
from pamd.models.data.splitting import SPLITS, default_fractions, split
from pamd.models.domain import derive
from pamd.models.kind import Kind, KindOptions, OptionSpec
from pamd.models.metrics import regression_metrics
from pamd.models.registry import KINDS, declared, save_model
from pamd.models.training import fit_with, rows_of
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

#: Names `--inputs` takes for a signal besides its own (seed 001 calls its third input
#: the change of length, delta L).
INPUT_ALIASES = {"delta_length": "delta_length_mm"}
#: Option parsers argparse applies itself; any other runs after parsing (its ModelError
#: names the flag and what to give).
_ARGPARSE_TYPES = (int, float, str)


def kind_flags() -> dict[str, list[tuple[Kind[KindOptions], OptionSpec]]]:
    """Each kind option's flag with the kinds that declare it (registry order); kinds
    that share an option name share the flag."""
    flags: dict[str, list[tuple[Kind[KindOptions], OptionSpec]]] = {}
    for k in KINDS.values():
        for spec in k.option_specs:
            flags.setdefault(spec.name, []).append((k, spec))
    return flags


def _add_kind_options(p: argparse.ArgumentParser) -> None:
    group = p.add_argument_group(
        "kind options", "each flag applies to the kinds it names (another kind refuses it)")
    for name, users in kind_flags().items():
        spec = users[0][1]
        if any(s.parse is not spec.parse or s.choices != spec.choices for _, s in users):
            raise ModelError(f"the kinds {', '.join(k.name for k, _ in users)} share the "
                             f"option {name} but parse it differently: rename one")
        group.add_argument(
            spec.flag, dest=name, default=None, metavar=spec.metavar,
            type=spec.parse if spec.parse in _ARGPARSE_TYPES else str, choices=spec.choices,
            help="; ".join(f"{k.name}: {s.help} (default {s.default_text})"
                           for k, s in users))


def kind_options_given(args: argparse.Namespace, kind: Kind[KindOptions]) -> dict[str, object]:
    """The kind options on the command line, parsed; one this kind lacks is refused."""
    given: dict[str, object] = {}
    mine = {s.name: s for s in kind.option_specs}
    for name, users in kind_flags().items():
        value = getattr(args, name, None)
        if value is None:
            continue
        spec = mine.get(name)
        if spec is None:
            raise ModelError(f"{users[0][1].flag} is an option of "
                             f"{', '.join(k.name for k, _ in users)}, not of --kind "
                             f"{kind.name} (its options: "
                             f"{', '.join(s.flag for s in mine.values()) or 'none'})")
        given[name] = value if spec.parse in _ARGPARSE_TYPES else spec.parse(value)
    return given


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "train", help="train an inverse model (ANFIS or another kind) or a forward force "
        "model from recorded runs or tables",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Train an inverse model (by default a first-order Sugeno ANFIS, "
        "hybrid learning) that maps the muscle's force and length (and optionally its "
        "velocity) to the pressure that produced them, from MCAP recordings (pamd run "
        "--record) or CSV files with named "
        "columns. Faults, limit-flagged samples, idle stretches, lead-in ramps and the "
        "first --settle-s of each run are dropped; the rest is decimated to --rate-hz and "
        "split into training / validation (/ test) sets by whole time blocks or runs.\n\n"
        "--target force_n --inputs pressure_bar,contraction trains a forward force model "
        "instead (seed 002's F(p, k)), e.g. on a datasheet map (a table without time: its "
        "rows are samples); --split-by curve holds out whole pressure curves and pamd "
        "evaluate --held-out judges them. A forward model is judged offline: the tick "
        "runs inverse models.\n\n"
        "--kind picks the model (the seeds' models; default anfis):\n"
        + "".join(f"  {k.help_line()}\n" for k in KINDS.values()),
        epilog="examples:\n"
        "  pamd train runs/sweep --out model.json             # a collection (pamd collect)\n"
        "  pamd train runs/sweep runs/half --out model.json --inputs force_n,length_mm,"
        "velocity_mm_s\n"
        "  pamd train runs/*.mcap --out model.json\n"
        "  pamd train runs/*.mcap --out model3.json --inputs force_n,length_mm,"
        "velocity_mm_s --mfs 3\n"
        "  pamd train lab_export.csv --out model.json --val-split 0 --epochs 50\n"
        "  pamd train runs/*.mcap --out tsf.json --kind ts-fuzzy --tuner mga --epochs 60\n"
        "  pamd train runs/*.mcap --out sarosi.json --kind sarosi\n"
        "  pamd train map.csv --out f.json --kind polynomial --target force_n "
        "--inputs pressure_bar,contraction --split-by curve   # seed 002's forward model")
    p.add_argument("data", nargs="+", metavar="DATA",
                   help="MCAP recordings, CSV files or directories: a collection (pamd "
                   "collect; its steps' files, as the manifest lists them) or a directory of "
                   "recordings (pamd run --record)")
    p.add_argument("--out", required=True, metavar="MODEL.json", help="model file to write")
    p.add_argument("--kind", default="anfis", choices=list(KINDS),
                   help="model kind (default anfis; see above)")
    p.add_argument("--inputs", default=None,
                   help=f"comma-separated model inputs from {', '.join(INPUT_UNITS)} "
                   "(delta_length_mm, or delta_length: seed 001's change of length, the "
                   "length's change over one sample period 1/--rate-hz, beside the "
                   "velocity; judged offline: the tick feeds velocity_mm_s) "
                   "(default per kind: " + "; ".join(
                       f"{k.name} {','.join(k.default_inputs)}" for k in KINDS.values()) + ")")
    p.add_argument("--target", "--output", dest="target", default="pressure_bar",
                   choices=sorted(OUTPUT_UNITS), metavar="SIGNAL",
                   help="the signal the model predicts, one of "
                   f"{', '.join(sorted(OUTPUT_UNITS))} (default pressure_bar, the inverse "
                   "model the feedforward runs; force_n with --inputs pressure_bar,contraction"
                   " is seed 002's forward force model F(p, k), judged offline; without "
                   "--inputs, the kind's default inputs with the target replaced by "
                   "pressure_bar). Another target only for the kinds that can predict it: "
                   + "; ".join(f"{k.name} {','.join(k.outputs)}" for k in KINDS.values()))
    p.add_argument("--val-split", type=float, default=None, metavar="FRACTION",
                   help="share of the data held out for validation (the best epoch on it is "
                   "kept); 0 trains on all DATA (default 0.2; --split-by random: 0.15)")
    p.add_argument("--test-split", type=float, default=None, metavar="FRACTION",
                   help="share held out as a test set, reported and never trained on "
                   "(default 0: test with pamd evaluate on other runs; --split-by random: "
                   "0.15, the papers' 70/15/15)")
    p.add_argument("--split-by", choices=SPLITS, default="block",
                   help="hold out whole time blocks (default), whole runs, whole pressure "
                   "curves of a map (rows sharing a pressure_bar value: a datasheet map is "
                   "judged on curves it never saw), or single samples drawn at random "
                   "(random: the papers' protocol, 70/15/15 by default; a recorded "
                   "sample's neighbours then train, so its held-out figures are near "
                   "in-sample ones). pamd evaluate --held-out validation|test finds the "
                   "parts again")
    p.add_argument("--block-s", type=float, default=10.0, help="block length for "
                   "--split-by block (default 10 s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the split (the same seed "
                   "and data give the same parts) and of the kind's random choices (GA, MLP "
                   "initialisation; default 0)")
    p.add_argument("--muscle", help="MCAP: only this muscle (default: every muscle)")
    add_actuation_option(p, "default: proportional")
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
    p.add_argument("--quiet", action="store_true", help="no progress bars (reading, "
                   "each training start)")
    _add_kind_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    kind = declared(args.kind)
    options = kind.make_options(kind_options_given(args, kind))
    inputs = model_inputs(args.inputs, kind, args.target)
    if args.target not in kind.outputs:
        raise ModelError(f"--target {args.target}: a {kind.name} model predicts "
                         f"{' or '.join(kind.outputs)}")
    opts = ExtractOptions(inputs=inputs, output=args.target, muscle=args.muscle,
                          settle_s=args.settle_s, rate_hz=args.rate_hz,
                          velocity_window_s=args.velocity_window_s, actuation=args.actuation)
    options.check(inputs)
    d = os.path.dirname(os.path.abspath(args.out))
    if not os.path.isdir(d):
        raise ModelError(f"--out {args.out}: directory {d} does not exist")
    t0 = time.monotonic()
    reading = progress.Reading(data_files(args.data), args.quiet)
    try:  # recordings and tables (CSV, MAT)
        samples = load_samples(args.data, opts, on_file=reading.file_read)
    finally:
        reading.close()
    read_s = time.monotonic() - t0
    say_own_actuations(samples, "pamd train")
    val_split, test_split = default_fractions(args.split_by, args.val_split,
                                              args.test_split)
    parts = split(samples, val_split, test_split, by=args.split_by,
                  block_s=args.block_s, seed=args.seed)
    tr, va, te = parts.train, parts.validation, parts.test
    print(f"pamd train: {len(samples)} samples from {len(samples.runs)} run(s) "
          f"({', '.join(inputs)} -> {args.target}), read in {progress.wall_text(read_s)}; "
          f"training {len(tr)}, validation {len(va) if va else 0}, test "
          f"{len(te) if te else 0} (split by {args.split_by})", file=sys.stderr)
    steps, unit, error = kind.progress(options) if kind.progress else (0, "", "")
    starts = kind.starts(options) if kind.starts else 1
    training = progress.Training(steps, starts, unit, error, args.quiet or not kind.progress)
    # where the data lay: the training domain the tick judges the model by
    prov: JsonObject = {"data": samples.provenance(), "split": parts.how,
                        "domain": derive(tr.X, tr.y, inputs, args.target).to_json()}
    try:
        fitted = fit_with(kind.name, samples, parts, options, seed=args.seed,
                          derived_inputs=derived_inputs(inputs, args.velocity_window_s,
                                                        args.rate_hz),
                          provenance=prov, callback=training)
    finally:
        training.close()
    model = fitted.model
    how = model.provenance.get("training")
    for warning in (how.get("warnings") or []) if isinstance(how, dict) else []:
        print(f"pamd train: WARNING: {warning}", file=sys.stderr)
    rows: dict[str, dict[str, float]] = {
        k: model.metrics[k] for k in ("train", "validation") if k in model.metrics}
    if te is not None:
        rows["test"] = model.metrics["test"] = _test_metrics(model, samples, te)
    _refuse_poor_fit(model.metrics, args)
    save_model(model, args.out)
    print(f"{args.out}: " + (fitted.summary or f"{model.kind} model {model!r}, "
                             f"{model.n_params} parameters")
          + f"; {progress.wall_text(time.monotonic() - t0)} (wall time, reading included)")
    format_table(rows, model.output.unit)
    _print_forward(model, kind)
    return 0


def _print_forward(model: InverseModel, kind: Kind[KindOptions]) -> None:
    """The figures of the kind's forward model, where it has one."""
    fwd = {k[len("forward_"):]: v for k, v in model.metrics.items() if k.startswith("forward_")}
    if fwd and kind.forward is not None:
        print(f"  forward model ({kind.forward.label}):")
        format_table(fwd, kind.forward.unit)


def _test_metrics(model: InverseModel, samples: Samples, te: Samples) -> dict[str, float]:
    """The model's figures on the test part (a stateful model run over whole runs,
    scored on the test rows)."""
    if model.stateful:  # over whole runs, scored on the test rows
        y_all, _ = predict_samples(model, samples.X, samples.run)
        y_hat = y_all[rows_of(samples, te)]
    else:
        y_hat = model.predict(te.X)
    return regression_metrics(te.y, y_hat, model.n_params)


def model_inputs(text: str | None, kind: Kind[KindOptions], target: str) -> tuple[str, ...]:
    """The inputs `--inputs` names, or the kind's defaults with the target (when it is
    one of them) replaced by pressure_bar: a forward model of the same signals."""
    if text is not None:
        return tuple(INPUT_ALIASES.get(s.strip(), s.strip()) for s in text.split(",")
                     if s.strip())
    return tuple("pressure_bar" if n == target else n for n in kind.default_inputs)


def _refuse_poor_fit(metrics: JsonObject, args: argparse.Namespace) -> None:
    why = poor_fit(metrics)
    if why is not None and not args.allow_poor_fit:
        raise ModelError(f"{args.out} not written: {why}; check the inputs, the data and the "
                         "layout, or write it anyway with --allow-poor-fit")
    if why is not None:
        print(f"pamd train: WARNING: {why}; written anyway (--allow-poor-fit)",
              file=sys.stderr)

"""`pamd model`: model files. `save`: the model a running daemon has adapted online
(`adapt` in the length modes) written as a new model file, with its provenance.
`export` and `import`: a pamd Sugeno model (anfis, ts-fuzzy) as a MATLAB `.fis` file and
a MATLAB Sugeno `.fis` as a pamd model file (`pamd.models.fis`), for labs whose models
live in the Fuzzy Logic Toolbox (seeds 000 and 001 were made there).

For `save`, the daemon's loop copies the adapted consequents into the `adapt` command's
verdict between two ticks (`adapt --action parameters`); this client reads the source
model file the daemon loaded (or `--source`), checks its sha256 and writes the new file
in the same format as `pamd train` (`pamd.models.anfis.adapted`): `pamd run --model`,
`pamd evaluate` and the `model` command read it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from pamd.client.cli.net import add_client_args
from pamd.models.anfis.adapted import save_adapted
from pamd.models.data.samples import INPUT_UNITS, OUTPUT_UNITS
from pamd.models.fis import KINDS as FIS_KINDS
from pamd.models.fis import export_fis, import_fis, names_given
from pamd.models.registry import load_model, save_model
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.wire.errors import CommandRefused, ModelError

#: The line `pamd --help` shows (pamd.client.cli.main declares the same)
HELP = "model files: MATLAB .fis export and import; a running daemon's adapted model"

#: How long `pamd model save` waits for the daemon's answer by default, s.
SAVE_TIMEOUT_S = 10.0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("model", help=HELP, description="Model files: MATLAB .fis out "
                       "and in (export, import); the adapted model of a running daemon "
                       "(save, over Zenoh).")
    msub = p.add_subparsers(dest="model_command", metavar="ACTION", required=True)
    _add_export(msub)
    _add_import(msub)
    s = msub.add_parser(
        "save", help="write the model a running daemon adapted online as a new model file",
        description="Ask a running daemon for the adapted consequents of a muscle's model "
        "(the `adapt` command, `parameters`: copied between two ticks), and write them "
        "with the source model into a new model file, with the provenance of the "
        "adaptation (source file and sha256, start, duration, bounds, drift). The source "
        "file must be the one the daemon loaded (its sha256 is checked).",
        epilog="example: pamd model save --muscle m1 models/m1-adapted.json")
    s.add_argument("out", metavar="FILE", help="the new model file")
    s.add_argument("--muscle", required=True, help="the muscle whose model adapted")
    s.add_argument("--source", metavar="FILE", help="the source model file, if not at the "
                   "path the daemon loaded it from (e.g. on another machine)")
    add_client_args(s)
    s.set_defaults(func=save)


def save(args: argparse.Namespace) -> int:
    from pamd.client.remote import Client  # Zenoh: only for a running daemon

    with Client(args.zenoh_config, args.connect) as cl:
        rig = cl.rig(args.rig)
        verdict = cl.command(rig, "adapt", {"muscle": args.muscle, "action": "parameters"},
                             timeout_s=args.timeout or SAVE_TIMEOUT_S)
    if not verdict.get("ok"):
        raise CommandRefused(f"adapt parameters refused: {verdict.get('error')}")
    path = save_adapted(verdict, args.out, args.source)
    info = {k: verdict.get(k) for k in ("muscle", "updates", "adapted_s", "total_bar",
                                         "drift_bar", "state")}
    print(f"wrote {path}: {json.dumps(info)}", file=sys.stdout)
    return 0


def _add_export(msub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    e = msub.add_parser(
        "export", help="write a pamd ANFIS or TS model as a MATLAB .fis file (readfis)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write a Sugeno model (kind anfis or ts-fuzzy, inverse or forward) as "
        "a MATLAB Fuzzy Logic Toolbox FIS file (version 3.0 text: [System], [Input*], "
        "[Output1], [Rules]; gaussmf or gbellmf inputs, linear or constant outputs), in "
        "the signals' own units: pamd's scaled inputs are converted exactly (a Gaussian "
        "in scaled units is one in raw units, a linear consequent stays linear). MATLAB: "
        "fis = readfis('model.fis'); y = evalfis(fis, [force_n length_mm]).",
        epilog="example:\n  pamd model export runs/model.json --fis runs/model.fis")
    e.add_argument("model", metavar="MODEL.json", help="the pamd model file")
    e.add_argument("--fis", required=True, metavar="FILE", help="the .fis file to write")
    e.add_argument("--name", help="the FIS's Name= (default: the file's name)")
    e.set_defaults(func=run_export)


def _add_import(msub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    i = msub.add_parser(
        "import", help="turn a MATLAB Sugeno .fis into a pamd model file",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Read a MATLAB Sugeno FIS (a grid partition: one rule for every "
        "combination of the inputs' MFs, as genfis/anfis make it; gaussmf or gbellmf "
        "inputs, linear or constant outputs, AndMethod prod, DefuzzMethod wtaver) into a "
        "pamd model file that pamd evaluate judges and, for an inverse model (output "
        "pressure_bar), pamd run --model runs as feedforward. The inputs and the output "
        "are the pamd signals their Name= fields say, else what --inputs/--output name; "
        "the file's values are taken in those signals' units (said on import: force_n N, "
        "length_mm mm, pressure_bar bar, ...). A file pamd cannot hold (a Mamdani system, "
        "another MF type, rules naming a missing MF, ...) is refused naming the line and "
        "section.",
        epilog="examples:\n"
        "  pamd model import seed000.fis --out runs/seed000.json\n"
        "  pamd model import lab.fis --out runs/lab.json --inputs force_n,length_mm "
        "--output pressure_bar")
    i.add_argument("fis", metavar="FILE.fis", help="the MATLAB FIS file")
    i.add_argument("--out", required=True, metavar="MODEL.json",
                   help="the pamd model file to write")
    i.add_argument("--inputs", metavar="NAMES", help="the pamd signal of each input, "
                   f"in the file's order, comma-separated ({', '.join(INPUT_UNITS)}); "
                   "default: the inputs' Name= fields")
    i.add_argument("--output", metavar="NAME", help="the pamd signal the output is "
                   f"({', '.join(OUTPUT_UNITS)}); default: the output's Name= field")
    i.add_argument("--kind", choices=FIS_KINDS, default="anfis", help="the model file's "
                   "kind (default anfis; ts-fuzzy: seed 001's model)")
    i.add_argument("--velocity-window-s", type=float, default=None, metavar="S",
                   help="a velocity_mm_s input: the time constant of its filter "
                   f"(default {MODEL_VELOCITY_WINDOW_S:g} s, pamd's for its own models)")
    i.set_defaults(func=run_import)


def run_export(args: argparse.Namespace) -> int:
    model = load_model(args.model)
    path, notes = export_fis(model, args.fis, args.name)
    for note in notes:
        print(f"pamd model export: note: {note}", file=sys.stderr)
    print(f"wrote {path}: {model!r} as a Sugeno FIS (MATLAB: readfis)")
    return 0


def run_import(args: argparse.Namespace) -> int:
    if args.velocity_window_s is not None and not args.velocity_window_s > 0:
        raise ModelError("--velocity-window-s must be > 0 s")
    out_dir = os.path.dirname(os.path.abspath(args.out))
    if not os.path.isdir(out_dir):
        raise ModelError(f"--out {args.out}: directory {out_dir} does not exist")
    got = import_fis(args.fis, inputs=names_given(args.inputs), output=args.output,
                     kind=args.kind, velocity_window_s=args.velocity_window_s)
    for note in got.notes:
        print(f"pamd model import: {note}", file=sys.stderr)
    path = save_model(got.model, args.out)
    print(f"wrote {path}: {got.model!r}, {got.model.n_params} parameters")
    return 0

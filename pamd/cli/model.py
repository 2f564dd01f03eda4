"""`pamd model save`: the model a running daemon has adapted online (`adapt` in the
length modes) written as a new model file, with its provenance.

The daemon's loop copies the adapted consequents into the `adapt` command's verdict
between two ticks (`adapt --action parameters`); this client reads the source model
file the daemon loaded (or `--source`), checks its sha256 and writes the new file in
the same format as `pamd train` (`pamd.models.anfis.adapted`): `pamd run --model`,
`pamd evaluate` and the `model` command read it.
"""

from __future__ import annotations

import argparse
import json
import sys

from pamd.cli.net import add_client_args
from pamd.errors import CommandRefused
from pamd.models.anfis.adapted import save_adapted
from pamd.net.client.client import Client

#: How long `pamd model save` waits for the daemon's answer by default, s.
SAVE_TIMEOUT_S = 10.0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("model", help="the adapted model of a running daemon (over Zenoh)",
                       description="Model files from a running daemon.")
    msub = p.add_subparsers(dest="model_command", metavar="ACTION", required=True)
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

"""`pamd tare`: zero a load cell offline, on the configured rig (no daemon, no Zenoh),
with the rules of the running daemon's `tare` command."""

from __future__ import annotations

import argparse

from pamd.client.cli.offline import add_state_args, apply_offline, print_verdict
from pamd.wire.declare.jsonsafe import JsonObject


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "tare", help="zero a load cell (offline, on the configured rig)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Re-zero the force reading: the load cell's offset drifts. Opens the rig "
        "without a daemon: reads every sensor, waits until the muscle rests, tares, saves "
        "the calibration file and leaves the outputs as they were. Stop a running daemon "
        "first, or send it `tare` over Zenoh.\n\n"
        "A tare never calls a hanging load zero: with the muscle's configured load_kg above "
        "0 it is refused unless --load-kg says what hangs (the load cell then reads that "
        "weight); --load-kg must match the configured load (change it with `load` first); "
        "and a tare that would move the offset by more than safety.tare_tolerance_n (a load "
        "nobody declared) is refused too. Nothing is saved when refused.",
        epilog="examples:\n  pamd tare --config rig.yaml --muscle m1            # nothing hangs\n"
        "  pamd tare --config rig.yaml --muscle m1 --load-kg 30  # tare against 30 kg")
    p.add_argument("--config", metavar="FILE", help="rig config (default: built-in sim)")
    p.add_argument("--muscle", help="the muscle to tare (default: every muscle)")
    p.add_argument("--load-kg", type=float, metavar="KG",
                   help="the load hanging on the load cell now (default: none)")
    add_state_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    payload: JsonObject = {}
    if args.muscle:
        payload["muscle"] = args.muscle
    if args.load_kg is not None:
        payload["load_kg"] = args.load_kg
    verdict = apply_offline(args.config, "tare", payload, args.state_dir)
    if not args.json:
        print("pamd tare: force offsets saved")
    print_verdict(verdict, args.json)
    return 0

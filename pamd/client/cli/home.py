"""`pamd home`: set a muscle's length datum offline, on the configured rig (no daemon,
no Zenoh), with the rules of the running daemon's `home` command."""

from __future__ import annotations

import argparse

from pamd.client.cli.offline import add_state_args, apply_offline, print_verdict


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "home", help="set a muscle's length datum (offline, on the configured rig)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Tell pamd the muscle's true length now, measured by hand, so that its "
        "incremental length sensor reads lengths (and the contraction limits guard the right "
        "length). Opens the rig without a daemon: reads every sensor, waits until the muscle "
        "rests, sets its datum, saves the calibration file and leaves the outputs as they "
        "were. Stop a running daemon first, or send it `home` over Zenoh (pamd cmd home).\n\n"
        "Refused, with the reason and nothing saved: on an absolute length sensor (an "
        "absolute encoder, or `absolute: true` on the signal: it is its own datum); "
        "when the length disagrees with the one the nominal length, the load's stretch and "
        "the measured pressure make expected by more than safety.home_tolerance; while the "
        "muscle moves or its readings are not trusted.",
        epilog="example:\n  pamd home --config rig.yaml --muscle m1 --length-mm 204.5")
    p.add_argument("--config", metavar="FILE", help="rig config (default: built-in sim)")
    p.add_argument("--muscle", required=True, help="the muscle whose length to set")
    p.add_argument("--length-mm", type=float, required=True, metavar="MM",
                   help="its true length now, in mm")
    add_state_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    verdict = apply_offline(args.config, "home",
                            {"muscle": args.muscle, "length_mm": args.length_mm},
                            args.state_dir)
    if not args.json:
        print(f"pamd home: {args.muscle}'s length datum set at {args.length_mm:g} mm; saved")
    print_verdict(verdict, args.json)
    return 0

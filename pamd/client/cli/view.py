"""`pamd plot`: the figures of a recording, without a model (pamd.client.plots)."""

from __future__ import annotations

import argparse
import os
import warnings

from pamd.client.plots import write_plots
from pamd.client.recording import RecordingIncomplete, open_recording
from pamd.wire.errors import RecordingError


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "plot", help="figures of a recording: pressure, length, force, hysteresis (PNG)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Per muscle, one PNG each: pressure and setpoint against time, length "
        "and its target, force, and the pressure-contraction hysteresis loop of each "
        "hanging load (the running ticks). Several files or a collection directory are "
        "joined in order. Needs matplotlib (pip install 'pamd[plot]').",
        epilog="examples:\n"
        "  pamd plot rec/20260101-120000_sim_run.mcap\n"
        "  pamd plot runs/sweep --out figs/sweep --muscle m1   # a collection, all loads")
    p.add_argument("recording", metavar="RECORDING", nargs="+",
                   help="MCAP file(s) or a collection directory")
    p.add_argument("--out", metavar="PREFIX", help="files are PREFIX_<muscle>_<figure>.png "
                   "(default: beside the recording, named after it)")
    p.add_argument("--muscle", metavar="M", help="this muscle only (default: every one)")
    p.set_defaults(func=run_plot)


def run_plot(args: argparse.Namespace) -> int:

    source = args.recording[0] if len(args.recording) == 1 else args.recording
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RecordingIncomplete)
        rec = open_recording(source, muscle=args.muscle)
    for w in caught:
        print(f"pamd plot: warning: {w.message}")
    if args.muscle is not None and args.muscle not in rec.muscles:
        raise RecordingError(f"no muscle {args.muscle!r} recorded")
    first = os.path.normpath(args.recording[0])
    prefix = args.out or (first if os.path.isdir(first) else os.path.splitext(first)[0])
    if os.path.isdir(first) and not args.out:
        prefix = os.path.join(first, os.path.basename(first))
    for path in write_plots(rec, prefix, [args.muscle] if args.muscle else None):
        print(path)
    return 0

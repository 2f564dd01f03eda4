"""`pamd inspect`, `pamd export` and `pamd recover`: the recording tools.

Each prints one clear line and exits non-zero (RecordingError, code 6) on a missing,
empty, truncated or non-MCAP file; never a traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from pamd.client import export
from pamd.client.collection import inspect_collection, print_collection
from pamd.wire.errors import RecordingError
from pamd.wire.record import files


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("inspect", help="what a recording or a collection holds (channels, "
                       "counts, metadata, faults, lost records; steps, loads, files)",
                       description="FILE: an MCAP recording's channels, counts, metadata, "
                       "faults and lost records. DIR: a collection (pamd collect, or one "
                       "started over the network): its steps, loads, status, files and "
                       "duration, from its manifest and the files.")
    p.add_argument("file", metavar="FILE|DIR", help="an MCAP file written by pamd run "
                   "--record, or a collection directory")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run_inspect)
    e = sub.add_parser(
        "export", help="a recording for MATLAB (.mat) or as named CSV tables",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Export a recording (a file, several, or a collection directory, "
        "joined in order).\n\n--mat: one MATLAB struct per muscle (every tick field as a "
        "column, units, state/mode names, flag bits), plus loop, events and pamd (rig, "
        "files, loads, metadata); `load` reads it in MATLAB and Octave. Needs scipy "
        "(pip install 'pamd[mat]').\n--csv: per muscle and for the loop a CSV with named "
        "columns, times rounded to the tick, states and modes as names; the events; and "
        "<stem>.meta.json with units, codes and flag bits.",
        epilog="examples:\n  pamd export --mat run.mat rec/20260101-120000_sim_run.mcap\n"
        "  pamd export --csv out/ runs/sweep            # a whole collection\n"
        "  matlab> s = load('run.mat'); plot(s.m1.t_s, s.m1.pressure_bar)")
    e.add_argument("file", metavar="RECORDING", nargs="+", help="MCAP file(s) or a "
                   "collection directory")
    e.add_argument("--csv", metavar="DIR", help="directory for the CSV files")
    e.add_argument("--mat", metavar="OUT.mat", help="the MATLAB file to write")
    e.set_defaults(func=run_export)
    r = sub.add_parser("recover", help="turn an unfinished recording (crash, SIGKILL, power "
                       "cut) into a valid file holding every complete chunk")
    r.add_argument("file", metavar="FILE")
    r.add_argument("--out", metavar="FILE|DIR", help="output file, or a directory (e.g. on "
                   "another disk when the recording's is full) for FILE.recovered.mcap "
                   "(default: beside FILE). Refused before writing anything when its disk "
                   "lacks the room")
    r.add_argument("--force", action="store_true", help="rewrite even a finalised file")
    r.set_defaults(func=run_recover)


def _ns(v: object) -> str:
    return "-" if v is None else str(v)


def run_inspect(args: argparse.Namespace) -> int:
    if os.path.isdir(args.file):

        coll = inspect_collection(args.file)
        if args.json:
            print(json.dumps(coll, indent=2))
        else:
            print_collection(coll)
        return 0
    info = files.inspect(args.file)
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        out = sys.stdout
        print(f"{info['file']}: {info['status']}", file=out)
        print(f"  {info['size_bytes']} bytes, {info['chunks']} chunks, {info['message_count']} "
              f"messages, {info['duration_s']:.3f} s ({_ns(info['start_ns'])} .. "
              f"{_ns(info['end_ns'])} ns)", file=out)
        print("  channels:", file=out)
        for c in info["channels"]:
            print(f"    {c['topic']:<32} {c['messages']:>9}  {c['encoding']} {c['schema']}",
                  file=out)
        meta = info["metadata"].get("pamd", {})
        if meta:
            print(f"  pamd {meta.get('pamd_version', '?')} on {meta.get('host', '?')}, rig "
                  f"{meta.get('rig_id', '?')}, {meta.get('clock', '?')} clock at "
                  f"{meta.get('rate_hz', '?')} Hz, started {meta.get('started_at', '?')}",
                  file=out)
            if meta.get("note"):
                print(f"  note: {meta['note']}", file=out)
        print(f"  metadata: {', '.join(info['metadata']) or 'none'}", file=out)
        atts = ", ".join(f"{a['name']} ({a['bytes']} B)" for a in info["attachments"])
        print(f"  attachments: {atts or 'none'}", file=out)
        print(f"  lost records: {info['lost_records']}", file=out)
        print(f"  faults: {'; '.join(info['faults']) if info['faults'] else 'none'}", file=out)
    if not info["finalised"]:
        raise RecordingError(f"{args.file}: unfinished recording; run `pamd recover "
                             f"{args.file}` to write a valid copy")
    return 0


def run_export(args: argparse.Namespace) -> int:
    if not args.csv and not args.mat:
        raise RecordingError("say what to write: --mat OUT.mat, --csv DIR, or both")

    source = args.file[0] if len(args.file) == 1 else args.file
    if args.mat:
        r = export.export_mat(source, args.mat)
        ticks = ", ".join(f"{m} {n} ticks" for m, n in r["muscles"].items())
        print(f"{args.mat}: {ticks}, {r['events']} events, from {r['files']} file(s)")
    if args.csv:
        for what, (path, n) in export.export_named_csv(source, args.csv).items():
            print(f"{what}: {path}" + ("" if n < 0 else f" ({n} rows)"))
    return 0


def run_recover(args: argparse.Namespace) -> int:
    r = files.recover(args.file, args.out, args.force)
    if r["complete"]:
        print(f"{args.file}: {r['message']}")
        return 0
    print(f"{args.file}: recovered {r['messages']} messages in {r['chunks']} complete chunks "
          f"-> {r['out']} (dropped {r['bytes_dropped']} bytes of unfinished tail"
          f"{': ' + r['tail'] if r['tail'] else ''})")
    return 0

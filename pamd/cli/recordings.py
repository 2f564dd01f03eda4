"""`pamd inspect`, `pamd export` and `pamd recover`: the recording tools.

Each prints one clear line and exits non-zero (RecordingError, code 6) on a missing,
empty, truncated or non-MCAP file; never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from pamd.errors import RecordingError
from pamd.io import files


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("inspect", help="what a recording holds (channels, counts, metadata, "
                       "faults, lost records)")
    p.add_argument("file", metavar="FILE", help="an MCAP file written by pamd run --record")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run_inspect)
    e = sub.add_parser("export", help="one CSV per topic, for MATLAB and pandas")
    e.add_argument("file", metavar="FILE")
    e.add_argument("--csv", metavar="DIR", required=True, help="directory for the CSV files")
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


def _ns(v: Any) -> str:
    return "-" if v is None else str(v)


def run_inspect(args: argparse.Namespace) -> int:
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
    out = files.export_csv(args.file, args.csv)
    for topic, (path, n) in out.items():
        if n < 0:
            print(f"{topic}: skipped (not a flat message this tool can tabulate)")
        else:
            print(f"{topic}: {n} rows -> {path}")
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

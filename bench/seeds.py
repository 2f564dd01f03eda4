"""The five seeds' figures beside pamd's, one table (issue 29 item 4).

Each seed's comparison lives in its own module, bench/seed000.py .. bench/seed004.py,
with `rows(quick: bool) -> list[SeedRow]` (bench/seed_table.py): the paper's figure
beside pamd's, measured on the paper's protocol as closely as the simulated rig allows,
and what is not like-for-like. This script runs them in turn (progress on stderr, with
each seed's time; what a seed prints goes there too, so that stdout is the table) and
prints one table; a seed whose module is not there prints "not measured", and one
whose run fails prints the error (the other seeds still run).

    python bench/seeds.py                 # the papers' protocols (long: tens of minutes)
    python bench/seeds.py --quick         # a few minutes per seed at most
    python bench/seeds.py --markdown      # docs/explanation/seeds.md's table
    python bench/seeds.py --seed 004      # one seed (repeatable)
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import importlib  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/ (run or imported)

from seed_table import SeedRow, markdown  # noqa: E402

SEEDS = ("000", "001", "002", "003", "004")
NOT_MEASURED = "not measured"


def seed_rows(seed: str, quick: bool) -> list[SeedRow]:
    """One seed's rows; a missing module or a failed run is a row that says so."""
    name = f"seed{seed}"
    try:
        module = importlib.import_module(name)
    except ModuleNotFoundError as e:
        if e.name != name:  # the module is there, something it imports is not
            return [SeedRow(seed, "(all)", "-", f"failed: {e}", "-")]
        return [SeedRow(seed, "(all)", "-", NOT_MEASURED, f"bench/{name}.py not written yet")]
    try:
        with contextlib.redirect_stdout(sys.stderr):  # a seed's own output is progress
            rows: list[SeedRow] = module.rows(quick)
    except Exception as e:  # noqa: BLE001  (one seed's failure must not hide the others)
        traceback.print_exc(file=sys.stderr)
        return [SeedRow(seed, "(all)", "-", f"failed: {type(e).__name__}: {e}", "-")]
    return rows or [SeedRow(seed, "(all)", "-", NOT_MEASURED, f"bench/{name}.py gave no rows")]


def text(rows: list[SeedRow]) -> str:
    """The rows as a plain-text table (a terminal's)."""
    head = ("seed", "figure", "paper", "pamd", "like for like")
    cells = [head] + [(r.seed, r.figure, r.paper, r.pamd, r.like_for_like) for r in rows]
    widths = [min(max(len(c[i]) for c in cells), 60) for i in range(4)]
    lines = []
    for c in cells:
        lines.append("  ".join(c[i].ljust(widths[i]) for i in range(4)) + "  " + c[4])
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="The seeds' figures beside pamd's on the simulated rig, one table.",
        epilog="Each seed's protocol, and what is not like-for-like, is in the docstring "
               "of bench/seedNNN.py.")
    ap.add_argument("--quick", action="store_true",
                    help="each seed's quick protocol (a few minutes at most each)")
    ap.add_argument("--markdown", action="store_true",
                    help="print a Markdown table (docs/explanation/seeds.md's form)")
    ap.add_argument("--seed", action="append", choices=SEEDS, metavar="NNN",
                    help=f"only this seed ({', '.join(SEEDS)}); repeatable")
    a = ap.parse_args(argv)
    rows: list[SeedRow] = []
    for seed in a.seed or SEEDS:
        t0 = time.monotonic()
        print(f"seed {seed} ...", file=sys.stderr, flush=True)
        got = seed_rows(seed, a.quick)
        print(f"seed {seed}: {len(got)} rows in {time.monotonic() - t0:.0f} s",
              file=sys.stderr, flush=True)
        rows += got
    print(markdown(rows) if a.markdown else text(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

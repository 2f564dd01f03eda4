"""The five seeds' figures beside pamd's, two tables (issue 29 item 4, issue 46 item 1).

Each seed's comparison lives in its own module, bench/seed000.py .. bench/seed004.py,
with `rows(quick: bool, data: str | None = None) -> list[SeedRow]`
(bench/seed_table.py): the paper's figure beside pamd's, each row under a named
protocol, the paper's own (its split, its metric basis, its per-condition fits) or
pamd's stricter one (loads never trained on, held-out curves), and what is not
like-for-like. This script runs them in turn (progress on stderr, with each seed's
time; what a seed prints goes there too, so that stdout is the tables) and prints one
table per protocol; a seed whose module is not there prints "not measured", one whose
run fails prints the error, and a seed the data cannot serve says why (the other seeds
still run).

    python bench/seeds.py                 # the simulated rig, full protocols (~15 min)
    python bench/seeds.py --quick         # a minute or two per seed at most
    python bench/seeds.py --markdown      # docs/explanation/seeds.md's tables
    python bench/seeds.py --seed 004      # one seed (repeatable)
    python bench/seeds.py --data runs/sweep   # a lab's recordings or tables instead
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

from seed_data import DataRefused  # noqa: E402
from seed_table import PAMD, PAPER, PROTOCOL_TITLES, SeedRow, markdown  # noqa: E402

SEEDS = ("000", "001", "002", "003", "004")
NOT_MEASURED = "not measured"


def seed_rows(seed: str, quick: bool, data: str | None = None) -> list[SeedRow]:
    """One seed's rows; a missing module, a failed run or data the seed cannot use is a
    row that says so."""
    name = f"seed{seed}"
    try:
        module = importlib.import_module(name)
    except ModuleNotFoundError as e:
        if e.name != name:  # the module is there, something it imports is not
            return [SeedRow(seed, "(all)", "-", f"failed: {e}", "-")]
        return [SeedRow(seed, "(all)", "-", NOT_MEASURED, f"bench/{name}.py not written yet")]
    try:
        with contextlib.redirect_stdout(sys.stderr):  # a seed's own output is progress
            rows: list[SeedRow] = (module.rows(quick) if data is None
                                   else module.rows(quick, data=data))
    except DataRefused as e:  # the lab's data cannot run this paper's protocol
        return [SeedRow(seed, "(all)", "-", f"refused: {e}", "-")]
    except Exception as e:  # noqa: BLE001  (one seed's failure must not hide the others)
        traceback.print_exc(file=sys.stderr)
        return [SeedRow(seed, "(all)", "-", f"failed: {type(e).__name__}: {e}", "-")]
    return rows or [SeedRow(seed, "(all)", "-", NOT_MEASURED, f"bench/{name}.py gave no rows")]


def cpu_s() -> float:
    """CPU seconds of this process and its finished children (the daemon's io process)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def text(rows: list[SeedRow]) -> str:
    """The rows as plain-text tables (a terminal's), one per protocol."""
    head = ("seed", "figure", "paper", "pamd", "like for like")
    out: list[str] = []
    for protocol in (PAPER, PAMD):
        mine = [r for r in rows if r.protocol == protocol]
        if not mine:
            continue
        cells = [head] + [(r.seed, r.figure, r.paper, r.pamd, r.like_for_like) for r in mine]
        widths = [min(max(len(c[i]) for c in cells), 60) for i in range(4)]
        out += (["", ""] if out else []) + [PROTOCOL_TITLES[protocol] + ":"]
        out += ["  ".join(c[i].ljust(widths[i]) for i in range(4)) + "  " + c[4]
                for c in cells]
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="The seeds' figures beside pamd's on the simulated rig, one table.",
        epilog="Each seed's protocol, and what is not like-for-like, is in the docstring "
               "of bench/seedNNN.py.")
    ap.add_argument("--quick", action="store_true",
                    help="each seed's quick protocol (a few minutes at most each)")
    ap.add_argument("--markdown", action="store_true",
                    help="print Markdown tables (docs/explanation/seeds.md's form)")
    ap.add_argument("--seed", action="append", choices=SEEDS, metavar="NNN",
                    help=f"only this seed ({', '.join(SEEDS)}); repeatable")
    ap.add_argument("--data", metavar="FILE|DIR",
                    help="a lab's own data instead of the simulated rig: MCAP recordings or "
                    "a collection, CSV or MAT tables (a directory of them: a file per "
                    "condition or load), with the columns each paper needs (force_n, "
                    "length_mm, pressure_bar, contraction, load_kg, target_length_mm); a "
                    "seed whose columns are missing says which")
    a = ap.parse_args(argv)
    rows: list[SeedRow] = []
    t_all, cpu_all = time.monotonic(), cpu_s()
    for seed in a.seed or SEEDS:
        t0, c0 = time.monotonic(), cpu_s()
        print(f"seed {seed} ...", file=sys.stderr, flush=True)
        got = seed_rows(seed, a.quick, a.data)
        print(f"seed {seed}: {len(got)} rows in {time.monotonic() - t0:.0f} s "
              f"({cpu_s() - c0:.0f} s of CPU)", file=sys.stderr, flush=True)
        rows += got
    print(f"all seeds: {time.monotonic() - t_all:.0f} s ({cpu_s() - cpu_all:.0f} "
          f"s of CPU; load average {os.getloadavg()[0]:.1f} at the end)", file=sys.stderr)
    print(markdown(rows) if a.markdown else text(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

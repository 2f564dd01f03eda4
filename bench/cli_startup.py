"""The CPU time `pamd` spends before it does anything (issue 26): `pamd --help` and
`pamd run --help`, each against a bare interpreter (`python -c pass`) in the same run,
so the machine's load falls on both alike.

Each command runs `--repeat` times in a fresh process (`python -m pamd ...`, what the
console script runs); its CPU time is user + system from the kernel's accounting of
that child (os.wait4), not the wall clock, with the modules' bytecode cached as in an
installed pamd (one unmeasured run of each command first). Prints per command the
median CPU time, its ratio to the bare interpreter's, and the pamd modules it imported.

    python bench/cli_startup.py [--repeat 7]
    python bench/cli_startup.py --pythonpath /work/main   # a before figure (another tree)
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: (label, interpreter arguments): the baseline first
COMMANDS: list[tuple[str, list[str]]] = [
    ("python -c pass (bare interpreter)", ["-c", "pass"]),
    ("pamd --help", ["-m", "pamd", "--help"]),
    ("pamd run --help", ["-m", "pamd", "run", "--help"]),
    ("pamd status --help", ["-m", "pamd", "status", "--help"]),
]

#: counts the pamd modules a command imported (run at the interpreter's exit)
_COUNT = ("import atexit, sys, runpy; atexit.register(lambda: print(sum(m.startswith('pamd') "
          "for m in sys.modules), file=sys.stderr)); sys.argv = ['pamd', *sys.argv[1:]]; "
          "runpy.run_module('pamd', run_name='__main__')")


def cpu_s(args: list[str], env: dict[str, str], cwd: Path) -> float:
    """User + system CPU seconds of one fresh `python ARGS` (its output discarded)."""
    proc = subprocess.Popen([sys.executable, *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=env, cwd=cwd)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"python {' '.join(args)} exited with {proc.returncode}")
    return usage.ru_utime + usage.ru_stime


def pamd_modules(args: list[str], env: dict[str, str], cwd: Path) -> int | None:
    """How many pamd modules `python -m pamd ARGS` imports (None for the baseline)."""
    if args[:2] != ["-m", "pamd"]:
        return None
    out = subprocess.run([sys.executable, "-c", _COUNT, *args[2:]], capture_output=True,
                         text=True, env=env, cwd=cwd, check=True)
    return int(out.stderr.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=7, help="fresh processes per command")
    ap.add_argument("--pythonpath", type=Path, help="measure the pamd of this tree instead")
    opts = ap.parse_args()
    env = dict(os.environ)
    tree = (opts.pythonpath or REPO).resolve()  # `-m` puts the working directory first
    env["PYTHONPATH"] = str(tree)
    # as installed: the modules' bytecode cached (pip compiles it), so no run pays for
    # compiling; one unmeasured run of each command writes the cache first
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    for _, args in COMMANDS:
        cpu_s(args, env, tree)
    rows = []
    for _ in range(opts.repeat):  # interleaved: a burst of load falls on every command
        rows.append([cpu_s(args, env, tree) for _, args in COMMANDS])
    medians = [statistics.median(r[i] for r in rows) for i in range(len(COMMANDS))]
    base = medians[0]
    print(f"CPU time (user + system), median of {opts.repeat} fresh processes; "
          f"pamd from {tree}")
    print(f"{'command':36s} {'cpu_s':>7s} {'x bare':>7s} {'pamd modules':>13s}")
    for (label, args), median in zip(COMMANDS, medians, strict=True):
        count = pamd_modules(args, env, tree)
        print(f"{label:36s} {median:7.3f} {median / base:7.1f} "
              f"{'-' if count is None else count:>13}")


if __name__ == "__main__":
    main()

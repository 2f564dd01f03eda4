"""The README's walk-through, exactly as written, and the figures it states (`-m slow`:
about three minutes of wall clock on a busy 2-core machine).

The commands are read from the README's walk-through block, not copied here, and run
in a fresh directory (the repository's `config/` linked in) on the virtual clock, where
every figure is deterministic. Each figure the walk-through's table states must be
what its command printed, to the digits the table shows. `pamd run` gets
`--no-telemetry` (no Zenoh session on the machine's default port; it changes no figure).
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
SECTION = "### Walk-through: from a collection to a model in the loop"


def section() -> str:
    text = README.read_text(encoding="utf-8")
    start = text.index(SECTION)
    end = text.index("\n## ", start)
    return text[start:end]


def commands(text: str) -> list[list[str]]:
    """The `pamd ...` lines of the section's first sh block, continuations joined."""
    block = text.split("```sh\n", 1)[1].split("```", 1)[0]
    joined = block.replace("\\\n", " ")
    return [shlex.split(line.split(" #", 1)[0]) for line in joined.splitlines()
            if line.startswith("pamd ")]


def run(cmd: list[str], cwd: Path) -> str:
    args = cmd[1:]
    if args[0] == "run":
        args.append("--no-telemetry")
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-m", "pamd", *args], capture_output=True, text=True,
                       timeout=900, cwd=cwd, env=env)
    assert r.returncode == 0, f"{shlex.join(cmd)}:\n{r.stdout}\n{r.stderr}"
    return r.stdout + r.stderr


def figure(pattern: str, out: str) -> str:
    m = re.search(pattern, out)
    assert m, f"{pattern!r} not in:\n{out}"
    return m.group(1)


#: a run summary's length max error (after its RMSE and MAE)
MAX_ERROR = r"length tracking RMSE \S+ mm, MAE \S+ mm, max error (\S+ mm)"


def test_the_walkthrough_writes_under_runs_and_installs_what_it_plots() -> None:
    """Every file the walk-through names for output is under runs/ (git ignores it; issue
    40: model.json and figs/ landed in the clone's root), and the block installs the
    plot extra its --plot needs before any command."""
    text = section()
    cmds = commands(text)
    outputs = [c[i + 1] for c in cmds for i, w in enumerate(c[:-1])
               if w in ("--out", "--record", "--plot")]
    assert len(outputs) == 6, outputs
    assert all(o.startswith("runs/") for o in outputs), outputs
    block = text.split("```sh\n", 1)[1]
    assert block.startswith("pip install '.[plot]'"), block[:80]
    assert any("--plot" in c for c in cmds)


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_the_readme_walkthrough_gives_the_readme_figures(tmp_path: Path) -> None:
    text = section()
    cmds = commands(text)
    verbs = [c[1] for c in cmds]
    assert verbs == ["collect", "collect", "train", "run", "run", "evaluate", "run", "run",
                     "evaluate"], verbs
    (tmp_path / "config").symlink_to(REPO / "config")
    outs = [run(c, tmp_path) for c in cmds]
    collect1, collect2, train, track, pid, evaluate, other, other_pid, evaluate2 = outs
    got = {
        "collect steps": figure(r"done; (\d+) step\(s\) finished", collect1) + " + "
        + figure(r"done; (\d+) step\(s\) finished", collect2),
        "train validation RMSE": figure(r"\n  RMSE\s+\S+\s+(\S+)", train),
        "train validation fit": figure(r"NRMSE fit %\s+\S+\s+(\S+)", train),
        "track RMSE": figure(r"length tracking RMSE (\S+ mm)", track),
        "track max": figure(MAX_ERROR, track),
        "PID RMSE": figure(r"length tracking RMSE (\S+ mm)", pid),
        "PID max": figure(MAX_ERROR, pid),
        "evaluate RMSE": figure(r"\n  RMSE\s+(\S+)", evaluate),
        "evaluate fit": figure(r"NRMSE fit %\s+(\S+)", evaluate),
        "evaluate max dev": figure(r"max deviation %\s+(\S+)", evaluate),
        "evaluate clipped": figure(r"(\d+ \(\S+ %\)) had inputs", evaluate),
        "other RMSE": figure(r"length tracking RMSE (\S+ mm)", other),
        "other max": figure(MAX_ERROR, other),
        "other PID RMSE": figure(r"length tracking RMSE (\S+ mm)", other_pid),
        "other PID max": figure(MAX_ERROR, other_pid),
        "other evaluate RMSE": figure(r"\n  RMSE\s+(\S+)", evaluate2),
        "other evaluate fit": figure(r"NRMSE fit %\s+(\S+)", evaluate2),
    }
    print(got)
    missing = {k: v for k, v in got.items() if v not in text}
    assert not missing, f"figures the README does not state: {missing}"
    for part in ("prediction", "error", "membership", "surface"):
        assert (tmp_path / "runs" / "figs" / f"track_{part}.png").stat().st_size > 5000
    # everything the walk-through writes is under runs/ (the clone's .gitignore has it)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["config", "runs"]

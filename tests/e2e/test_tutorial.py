"""The tutorial (docs/tutorial.md), exactly as written, and the figures it states
(`-m slow`: about three minutes of wall clock on a busy 2-core machine); and, in every
run, that its commands are what a reader needs: they parse, they write under runs/,
and the page installs the plot extra its --plot needs before any of them.

The commands are read from the page's sh blocks (tests/tutorial.py), not copied here,
and run in a fresh directory (the repository's `config/` linked in) on the virtual
clock, where every figure is deterministic. Each figure the page states must be what
its command printed, to the digits the page shows. `pamd run` gets `--no-telemetry`
(no Zenoh session on the machine's default port; it changes no figure). The default
run's shortened copy: tests/e2e/test_walkthrough.py.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from pamd.client.cli.main import build_parser
from tests.tutorial import REPO, commands, page, sh_blocks

#: the verbs of the tutorial's steps, in order
VERBS = ["collect", "collect", "train", "run", "run", "evaluate", "run", "run", "evaluate"]


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


def test_the_tutorials_commands_parse_and_write_under_runs() -> None:
    """Every command of the page parses as `pamd` parses it; every file it names for
    output is under runs/ (git ignores it; issue 40: model.json and figs/ landed in the
    clone's root); the page installs the plot extra its --plot needs before any
    command; the plans it collects are shipped."""
    cmds = commands()
    assert [c[1] for c in cmds] == VERBS
    parser = build_parser()
    for c in cmds:
        assert callable(parser.parse_args(c[1:]).func), c
    outputs = [c[i + 1] for c in cmds for i, w in enumerate(c[:-1])
               if w in ("--out", "--record", "--plot")]
    assert len(outputs) == 6, outputs
    assert all(o.startswith("runs/") for o in outputs), outputs
    assert sh_blocks()[0].startswith("pip install '.[plot]'"), sh_blocks()[0][:80]
    assert any("--plot" in c for c in cmds)
    for c in cmds:
        if c[1] == "collect":
            assert (REPO / c[2]).is_file(), c


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_the_tutorial_gives_the_figures_it_states(tmp_path: Path) -> None:
    text = page()
    cmds = commands()
    assert [c[1] for c in cmds] == VERBS
    (tmp_path / "config").symlink_to(REPO / "config")
    outs = [run(c, tmp_path) for c in cmds]
    collect1, collect2, train, track, pid, evaluate, other, other_pid, evaluate2 = outs
    got = {
        "collect steps": figure(r"(done; \d+ step\(s\) finished)", collect1) + "` and `"
        + figure(r"(done; \d+ step\(s\) finished)", collect2),
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
    assert not missing, f"figures the tutorial does not state: {missing}"
    for part in ("prediction", "error", "membership", "surface"):
        assert (tmp_path / "runs" / "figs" / f"track_{part}.png").stat().st_size > 5000
    # everything the tutorial writes is under runs/ (the clone's .gitignore has it)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["config", "runs"]

"""The README's two commands are what CI runs: `.ci/run` calls exactly the test
command, and that command installs what the tests need before running them."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def the_two_commands() -> list[str]:
    readme = (REPO / "README.md").read_text()
    section = readme.split("## The two commands", 1)[1].split("\n## ", 1)[0]
    return [b.strip() for b in re.findall(r"```sh\n(.*?)```", section, re.S)]


def test_ci_runs_exactly_the_readme_test_command() -> None:
    install_and_run, test = the_two_commands()
    assert install_and_run.startswith("pip install . && pamd run")
    ci = (REPO / ".ci" / "run").read_text().splitlines()
    assert test in ci, f".ci/run does not call {test!r}"
    assert test.split(" && ")[0] == ".ci/setup-tests"


def test_the_setup_script_installs_every_tool_and_package_the_tests_need() -> None:
    script = REPO / ".ci" / "setup-tests"
    assert os.access(script, os.X_OK)
    text = script.read_text()
    for tool in ("socat", "openssl", "systemd-analyze", "node", "npm"):
        assert f"[{tool}]=" in text, tool
    assert "pip install -q -e '.[test]'" in text
    assert "npm ci --prefix tests/js" in text
    assert (REPO / "tests" / "js" / "package-lock.json").is_file()  # what npm ci installs


def quickstart_blocks() -> list[str]:
    readme = (REPO / "README.md").read_text()
    section = readme.split("## A ten-minute quickstart", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.*?)```", section, re.S)


def quickstart_commands(block: str) -> list[list[str]]:
    """A block's `pamd` commands (`;` separates several on a line; comments cut)."""
    import shlex

    out = []
    for line in block.splitlines():
        for part in line.split(" #", 1)[0].split(";"):
            words = shlex.split(part)
            if words and words[0] == "pamd":
                out.append(words)
    return out


def test_the_quickstart_commands_parse() -> None:
    """Each `pamd` command of the quickstart is one `pamd` takes (its parser, the
    sub-command's options); the first block installs the plot extra `pamd plot` needs."""
    from pamd.client.cli.main import build_parser

    blocks = quickstart_blocks()
    assert len(blocks) == 3 and blocks[0].startswith("pip install '.[plot]'")
    parser = build_parser()
    cmds = [c for b in blocks for c in quickstart_commands(b)]
    assert len(cmds) >= 10
    for cmd in cmds:
        if cmd[1:] in (["--help"], ["run", "--help"]):
            continue
        assert callable(parser.parse_args(cmd[1:]).func), cmd


@pytest.mark.slow
def test_the_quickstarts_virtual_run_prints_what_the_readme_says(tmp_path: Path) -> None:
    """The first block, as written, in a fresh directory: the run's summary says what the
    README says it does (virtual clock: the same on every machine), and the recording
    it wrote opens, plots and exports."""
    import subprocess
    import sys

    (tmp_path / "config").symlink_to(REPO / "config")
    outs = []
    for cmd in quickstart_commands(quickstart_blocks()[0]):
        r = subprocess.run([sys.executable, "-m", "pamd", *cmd[1:]], cwd=tmp_path,
                           capture_output=True, text=True, timeout=600,
                           env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
        assert r.returncode == 0, (cmd, r.stdout, r.stderr)
        outs.append(r.stdout + r.stderr)
    readme = (REPO / "README.md").read_text()
    run = outs[0]
    for said in ("STARTING -> IDLE: sensors read; holding measured pressure",
                 "43604 ticks", "m1: pressure tracking RMSE 0.0034 bar"):
        assert said in run and said.split(": ", 1)[-1] in " ".join(readme.split()), said
    assert list((tmp_path / "runs" / "figs").glob("first_m1_*.png"))
    assert (tmp_path / "runs" / "csv" / "first_loop.csv").is_file()

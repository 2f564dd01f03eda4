"""The README's two commands are what CI runs: `.ci/run` calls exactly the test
command, and that command installs what the tests need before running them."""

from __future__ import annotations

import os
import re
from pathlib import Path

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

"""ruff over the project, in the suite (and so in CI), with the rules of pyproject.toml
(private access from outside a class included); and the pre-commit hooks run the same
checks as CI."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_passes() -> None:
    done = subprocess.run([sys.executable, "-m", "ruff", "check", "--output-format",
                           "concise", "."], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-2000:]


def test_pre_commit_runs_what_ci_runs() -> None:
    config = yaml.safe_load((ROOT / ".pre-commit-config.yaml").read_text())
    entries = {h["id"]: h["entry"] for repo in config["repos"] for h in repo["hooks"]}
    assert entries["ruff"] == "ruff check"
    assert entries["layers"].endswith("tests/test_architecture.py")
    assert entries["mypy"].endswith("tests/test_typing.py")

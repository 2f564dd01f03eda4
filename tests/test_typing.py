"""The type checker over pamd/ and drivers/, in the suite (and so in CI).

`drivers/` installs as `pamd.drivers`; mypy does not follow the editable install's
mapping, so the check runs on a tree of links that puts drivers/ where the package
sees it. Settings: `[tool.mypy]` in pyproject.toml (untyped functions are checked)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _linked_tree(into: Path) -> Path:
    package = into / "pamd"
    package.mkdir(parents=True)
    for child in (ROOT / "pamd").iterdir():
        if child.name != "__pycache__":
            (package / child.name).symlink_to(child)
    (package / "drivers").symlink_to(ROOT / "drivers")
    return into


def test_mypy_passes_on_pamd_and_its_drivers(tmp_path: Path) -> None:
    tree = _linked_tree(tmp_path / "tree")
    done = subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
         "--cache-dir", str(tmp_path / "cache"), "-p", "pamd"],
        cwd=tree, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-2000:]
    assert "no issues found" in done.stdout


def test_the_package_says_it_is_typed() -> None:
    assert (ROOT / "pamd" / "py.typed").is_file()
    assert (ROOT / "drivers" / "py.typed").is_file()

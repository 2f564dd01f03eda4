"""The type checker over pamd/ and drivers/, in the suite (and so in CI).

`drivers/` installs as `pamd.drivers`; mypy does not follow the editable install's
mapping, so the check runs on a tree of links that puts drivers/ where the package
sees it. Settings: `[tool.mypy]` in pyproject.toml (untyped functions are checked).

The tree and mypy's cache are kept in the checkout (.mypy_cache/suite/, which git
is told to ignore), so a run after a change re-checks what the change touched and
what depends on it, as mypy does for a developer (~12 s of one core cold, well under
a second warm). mypy re-checks a module whose source (or a dependency's interface)
changed and never caches a module with errors, so a warm run reports what a cold one
does. A second run of the suite in the same checkout at the same time takes a cold
temp directory instead (the lock below)."""

from __future__ import annotations

import atexit
import fcntl
import importlib.metadata
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import IO

import pytest

ROOT = Path(__file__).resolve().parents[1]


KEPT = ROOT / ".mypy_cache" / "suite"  # the tree and cache kept between runs


def _linked_tree(into: Path) -> Path:
    package = into / "pamd"
    shutil.rmtree(package, ignore_errors=True)  # links made again: a module added or gone
    package.mkdir(parents=True)
    for child in (ROOT / "pamd").iterdir():
        if child.name != "__pycache__":
            (package / child.name).symlink_to(child)
    (package / "drivers").symlink_to(ROOT / "drivers")
    return into


def _kept_dir() -> Path | None:
    """KEPT, locked for this process until it exits (mypy runs once a run); None if
    another run in this checkout holds it."""
    KEPT.mkdir(parents=True, exist_ok=True)
    (KEPT / ".gitignore").write_text("*\n")  # as mypy marks its own cache directories
    lock = (KEPT / "lock").open("w")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        return None
    _held.append(lock)  # open (and so locked) until this process ends
    return KEPT


_held: list[IO[str]] = []


def _start_mypy(into: Path) -> subprocess.Popen[str]:
    """mypy over the linked tree in `into`, at a low CPU priority (it yields the cores
    to the tests running beside it)."""
    tree = _linked_tree(into / "tree")
    return subprocess.Popen(
        [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
         "--cache-dir", str(into / "cache"), "-p", "pamd"],
        cwd=tree, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: os.nice(10))  # started before any test's thread


#: mypy started by `start_early` (tests/conftest.py), with its scratch directory
_early: dict[str, tuple[subprocess.Popen[str], Path]] = {}


def start_early(chosen: set[str]) -> None:
    """Once the run's tests are chosen (tests/conftest.py calls this with the names of
    this file's chosen tests): if the mypy test is among them, mypy starts at once and
    checks the package while the tests before this file run, on the second core, so the
    test only waits for what is left (the same check as starting it in the test, which
    takes ~12 s of one core)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return  # each worker chose every test: the one that gets this file starts mypy
    if ("test_mypy_passes_on_pamd_and_its_drivers" in chosen and "mypy" not in _early
            and _numpy_types_it()):
        into = _kept_dir() or Path(tempfile.mkdtemp(prefix="pamd-mypy-"))
        _early["mypy"] = (_start_mypy(into), into)
        atexit.register(_stop_early)


def _stop_early() -> None:
    """A run that ends before the mypy test (-x, Ctrl-C) leaves no mypy behind."""
    for proc, into in _early.values():
        proc.kill()
        proc.communicate()
        if into != KEPT:
            shutil.rmtree(into, ignore_errors=True)
    _early.clear()


#: The numpy whose type stubs pamd's annotations are checked against: a bare
#: `np.ndarray` takes the stubs' own defaults from numpy 2.4 on. Older numpy runs pamd
#: (pyproject: numpy>=1.26) but its stubs cannot check it (issue 38, measured: 1.26-2.2
#: report 302-310 missing type arguments, 2.3 one Any returned); pip resolves the newest.
TYPING_NUMPY = (2, 4)


def _numpy_types_it() -> bool:
    """The installed numpy's stubs are those pamd's annotations are checked against."""
    installed = tuple(int(x) for x in importlib.metadata.version("numpy").split(".")[:2])
    return installed >= TYPING_NUMPY


def test_mypy_passes_on_pamd_and_its_drivers(tmp_path: Path) -> None:
    if not _numpy_types_it():
        pytest.skip(f"numpy {importlib.metadata.version('numpy')}'s type stubs predate the "
                    f"numpy {TYPING_NUMPY[0]}.{TYPING_NUMPY[1]} pamd's annotations are "
                    "checked against; pamd runs on it, the type check needs pip install "
                    f"'numpy>={TYPING_NUMPY[0]}.{TYPING_NUMPY[1]}'")
    if "mypy" not in _early:
        into = _kept_dir() or tmp_path
        _early["mypy"] = (_start_mypy(into), into)
    proc, into = _early.pop("mypy")
    try:
        out, err = proc.communicate(timeout=600)
    finally:
        proc.kill()
        if into != KEPT:
            shutil.rmtree(into, ignore_errors=True)
    assert proc.returncode == 0, out[-6000:] + err[-2000:]
    assert "no issues found" in out


def test_the_package_says_it_is_typed() -> None:
    assert (ROOT / "pamd" / "py.typed").is_file()
    assert (ROOT / "drivers" / "py.typed").is_file()

"""Build a session fixture's files once per test run, not once per xdist worker.

A session fixture is per process: with `-n 3` each worker that runs one of its tests
builds it again (tests/models' recorded sweeps and trained models: ~10 s of CPU each
time). `once_per_run(factory, name, build)` builds into a directory of the run's own
temp root, shared by its workers (pytest's basetemp is `<run>/popen-gwN` per worker),
under an exclusive lock: the first worker builds, the others wait and read what it
wrote. `build(dir)` writes its files into `dir` and returns a JSON value (paths as
strings) that the fixture turns back into what it yields. A build that raises leaves
nothing behind, so the next worker tries (and fails, saying why) itself. Without xdist
it simply builds.

Only for files that tests read and never change (a test writes into its own tmp_path).
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest


def once_per_run(factory: pytest.TempPathFactory, name: str,
                 build: Callable[[Path], Any]) -> Any:  # Any: a JSON value, the fixture's
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return build(factory.mktemp(name))
    shared = factory.getbasetemp().parent / "once"
    shared.mkdir(exist_ok=True)
    done = shared / f"{name}.json"
    with (shared / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if done.is_file():
            return json.loads(done.read_text())
        into = shared / name
        shutil.rmtree(into, ignore_errors=True)  # a failed build's leftovers
        into.mkdir()
        value = build(into)
        tmp = done.with_suffix(".tmp")
        tmp.write_text(json.dumps(value))
        tmp.replace(done)
        return value

"""Helpers of the viewing tests: a Foxglove viewer that is not pamd's code (the
protocol's own client library under Node, tests/js/foxglove_view.js) as a process."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tests.once import once_per_run

JS = Path(__file__).resolve().parents[1] / "js"


def node_viewer() -> list[str]:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed (CI installs it and runs `npm ci` in tests/js)")
    if not (JS / "node_modules" / "@foxglove" / "ws-protocol").is_dir():
        pytest.fail("tests/js/node_modules missing: run `npm ci --prefix tests/js`")
    return [node, str(JS / "foxglove_view.js")]


class Viewer:
    """`node foxglove_view.js URL ARGS` in the background; `result()` its JSON."""

    def __init__(self, tmp: Path, url: str, *args: str, name: str = "viewer") -> None:
        self.out, self.err = tmp / f"{name}.json", tmp / f"{name}.err"
        with open(self.out, "w") as out, open(self.err, "w") as err:
            self.proc = subprocess.Popen([*node_viewer(), url, *args], stdout=out, stderr=err)

    def wait_receiving(self, timeout_s: float = 60.0) -> None:
        deadline = time.monotonic() + timeout_s
        while "receiving" not in self.err.read_text():
            if self.proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the viewer received nothing: {self.err.read_text()[-2000:]} "
                            f"{self.out.read_text()[-2000:]}")
            time.sleep(0.05)

    def result(self, timeout_s: float = 120.0) -> dict[str, Any]:
        try:
            self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            pytest.fail("the viewer did not finish")
        return json.loads(self.out.read_text())

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


def pamd_cli(*args: str | Path, cwd: Path | None = None,
             timeout_s: float = 300.0) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-m", "pamd", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout_s, cwd=cwd, env=env)


PLAN = """name: mini
muscle: m1
settle: {seconds: 0.5}
profile: {kind: sine, min_bar: 1.0, max_bar: 3.0, freq_hz: 0.5, cycles: 1}
steps:
  - {name: load-15kg, load_kg: 15}
  - {name: load-40kg, load_kg: 40}
"""


@dataclass
class Recorded:
    file: Path
    summary: dict[str, Any]


@pytest.fixture(scope="session")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Recorded:
    """`pamd run` on the virtual clock: a 0.5 Hz sine of 1-3 bar, 4 s, recorded."""
    def build(d: Path) -> dict[str, Any]:
        r = pamd_cli("run", "--clock", "virtual", "--duration", "4", "--record", d / "rec",
                     "--profile", "sine", "--freq-hz", "0.5", "--min-bar", "1", "--max-bar",
                     "3", "--json", cwd=d)
        assert r.returncode == 0, r.stderr
        summary: dict[str, Any] = json.loads(r.stdout)
        return summary

    summary = once_per_run(tmp_path_factory, "view-recorded", build)  # tests/once.py
    (file,) = summary["recording"]["files"]
    return Recorded(Path(file), summary)


@pytest.fixture(scope="session")
def collection(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`pamd collect` of a two-step plan (15 kg, 40 kg) on the virtual clock."""
    def build(d: Path) -> str:
        (d / "plan.yaml").write_text(PLAN)
        r = pamd_cli("collect", d / "plan.yaml", "--clock", "virtual", "--out", d / "coll",
                     "--no-progress", cwd=d)
        assert r.returncode == 0, r.stderr
        return str(d / "coll")

    return Path(once_per_run(tmp_path_factory, "view-collection", build))  # tests/once.py

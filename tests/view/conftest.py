"""Helpers of the viewing tests: a Foxglove viewer that is not pamd's code (the
protocol's own client library under Node, tests/js/foxglove_view.js) as a process."""

from __future__ import annotations

import json
import shutil
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest

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

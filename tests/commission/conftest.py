"""Commissioning on the simulated rig (virtual clock: deterministic): the CLI run in
this process, its JSON report, and the proposed thresholds put to the test."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import yaml

from pamd.client.cli.main import main
from pamd.config import load_config
from pamd.loop.harness import Harness

REPO = Path(__file__).resolve().parents[2]
#: how long the proposed thresholds run a healthy rig: a minute of virtual time (three
#: cycles of the 0.05 Hz sine over the whole range); `-m slow`: five minutes
SOAK_S = 60.0
LONG_SOAK_S = 300.0
#: the commissioning runs of the fixtures: a shorter rest and holds than the default
#: (the figures need no more; the suite runs on a busy machine)
QUICK = ("--rest-s", "5", "--hold-s", "1.5")


def commission(config: Path, *args: str) -> tuple[int, dict[str, Any], str]:
    """`pamd commission CONFIG --clock virtual --json ARGS`: exit code, report, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["commission", str(config), "--clock", "virtual", "--json", *args])
    text = out.getvalue()
    return rc, (json.loads(text) if text.strip() else {}), err.getvalue()


def copy_config(name: str, into: Path, replace: tuple[tuple[str, str], ...] = ()) -> Path:
    """config/NAME copied into `into`, with text replacements (each must apply)."""
    text = (REPO / "config" / name).read_text()
    for old, new in replace:
        assert old in text, old
        text = text.replace(old, new)
    path = into / name
    path.write_text(text)
    return path


def with_faults(config: Path, faults: list[dict[str, Any]], into: Path) -> Path:
    """The config with the sim driver's fault schedule (comments dropped)."""
    raw = yaml.safe_load(config.read_text())
    raw["drivers"][0]["options"]["faults"] = faults
    path = into / f"faulty-{config.name}"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def sine_rig(config: Path) -> Harness:
    """The rig of `config` on the virtual clock, running the seeds' 0-6 bar sine."""
    h = Harness(load_config(str(config), {"loop": {"clock": "virtual"}}))
    h.step(0.01)
    verdict = h.cmd("profile", kind="sine", min_bar=0.0, max_bar=6.0, freq_hz=0.05,
                    cycles=20)
    assert verdict["ok"], verdict
    return h


def proposed(report: dict[str, Any]) -> dict[str, float]:
    return {r["key"]: r["proposed"] for r in report["thresholds"] if r["proposed"] is not None}

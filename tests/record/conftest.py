"""Helpers of the recording tests: a virtual daemon run that records into a temp dir
while a capture sink keeps, in-process, every record and event the loop produced."""

from __future__ import annotations

import copy
import json
import math
from array import array
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.config import LoadedConfig, load_config
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.wire.declare import events
from pamd.wire.declare.jsonsafe import dumps

SIM_YAML = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"


def _merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in changes.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def make_sim_config(tmp_path: Path, load_kg: float = 30.0, **changes: Any) -> LoadedConfig:
    """config/sim.yaml with the virtual clock, real-time off, and `changes` merged in."""
    base = yaml.safe_load(SIM_YAML.read_text())
    base["loop"]["clock"] = "virtual"
    base["loop"]["realtime"] = {"enabled": False}
    base["telemetry"] = {"enabled": False}  # never on the default port 7447 in tests
    base["drivers"][0]["options"]["muscles"][0]["load_kg"] = load_kg
    base["muscles"][0]["load_kg"] = load_kg
    path = tmp_path / "sim.yaml"
    path.write_text(yaml.safe_dump(_merge(base, changes), sort_keys=False))
    return load_config(str(path))


@pytest.fixture
def sim_config(tmp_path: Path) -> Callable[..., LoadedConfig]:
    return lambda load_kg=30.0, **changes: make_sim_config(tmp_path, load_kg, **changes)


class CaptureSink:
    """What the loop saw: a copy of every tick record and every event; each event is
    checked against its declaration (pamd.wire.declare.events) as it comes, and the
    `recorded_run` fixture fails on any that drifted."""

    def __init__(self) -> None:
        self.rows: list[list[float]] = []
        self.events: list[tuple[float, str, dict[str, Any]]] = []
        self.undeclared: list[str] = []

    def put(self, record: array) -> bool:
        self.rows.append(record.tolist())
        return True

    def event(self, t_s: float, kind: str, data: dict[str, Any]) -> None:
        self.events.append((t_s, kind, data))
        self.undeclared += events.problems(kind, json.loads(dumps(data)))

    def close(self) -> None:
        pass


def same(a: Any, b: Any) -> bool:
    """Equal, with NaN equal to NaN (and to a JSON 'NaN' string)."""
    fa = float("nan") if a == "NaN" else a
    fb = float("nan") if b == "NaN" else b
    if isinstance(fa, float) and isinstance(fb, float) and math.isnan(fa) and math.isnan(fb):
        return True
    return fa == fb


class Run:
    def __init__(self, daemon: Daemon, cap: CaptureSink, result: dict[str, Any]) -> None:
        self.daemon = daemon
        self.cap = cap
        self.result = result
        self.files = result["recording"]["files"] if result.get("recording") else []


@pytest.fixture
def recorded_run(tmp_path: Path, sim_config: Callable[..., Any]) -> Callable[..., Run]:
    def run(duration_s: float = 1.0, profile: dict[str, Any] | None = None,
            req: dict[str, Any] | None = None, load_kg: float = 30.0,
            **changes: Any) -> Run:
        cfg = sim_config(load_kg, **changes)
        rq = RecordingRequest(dir=str(tmp_path / "rec"), **(req or {}))
        d = Daemon(cfg, note="test note", recording=rq)
        cap = CaptureSink()
        d.summary.downstream.insert(0, cap)
        # Queued before the start: the loop applies it on its first tick after start-up,
        # so a virtual run is the same every time.
        pending = d.submit("profile", profile) if profile is not None else None
        d.start(duration_s)
        try:
            if pending is not None:
                verdict = pending.result(30.0)
                assert verdict["ok"], verdict
            d.wait(timeout_s=120)
        finally:
            d.stop("test finished")
            d.wait(timeout_s=60)
            d.close()
        assert not cap.undeclared, cap.undeclared
        return Run(d, cap, d.result())

    return run

"""Shared fixtures: a simulated rig in one line.

`sim_config(**changes)` writes a variant of config/sim.yaml into the test's temp
dir (virtual clock, real-time off) and loads it; `harness` steps a controller tick
by tick with the virtual clock, in this thread, deterministically; `sim_daemon`
is the whole daemon (loop thread and all) on the simulated rig.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import copy  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import pytest  # noqa: E402
import yaml  # noqa: E402

from pamd.calibration import load_calibration  # noqa: E402
from pamd.commands import apply_command, parse_command  # noqa: E402
from pamd.config import LoadedConfig, load_config  # noqa: E402
from pamd.controller import RigController  # noqa: E402
from pamd.daemon import Daemon  # noqa: E402
from pamd.loop import VirtualClock  # noqa: E402
from pamd.rig import Rig  # noqa: E402
from pamd.summary import SummarySink  # noqa: E402
from pamd.tick import TickLayout  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SIM_YAML = REPO / "config" / "sim.yaml"


def merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """Deep-merge `changes` into a copy of `base` (lists are replaced)."""
    out = copy.deepcopy(base)
    for k, v in changes.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = v
    return out


def sim_dict(load_kg: float = 30.0, **changes: Any) -> dict[str, Any]:
    """config/sim.yaml as a dict, virtual clock, real-time off, with changes."""
    base = yaml.safe_load(SIM_YAML.read_text())
    base["loop"]["clock"] = "virtual"
    base["loop"]["realtime"] = {"enabled": False}
    base["drivers"][0]["options"]["muscles"][0]["load_kg"] = load_kg
    base["muscles"][0]["load_kg"] = load_kg
    return merge(base, changes)


@pytest.fixture
def sim_config(tmp_path: Path) -> Callable[..., LoadedConfig]:
    def make(load_kg: float = 30.0, **changes: Any) -> LoadedConfig:
        path = tmp_path / "sim.yaml"
        path.write_text(yaml.safe_dump(sim_dict(load_kg, **changes), sort_keys=False))
        return load_config(str(path))

    return make


class Harness:
    """A controller stepped tick by tick on the virtual clock, in the test's thread."""

    def __init__(self, cfg: LoadedConfig) -> None:
        self.cfg = cfg
        self.period_s = cfg.period_s
        self.calibration = load_calibration(cfg.calibration_path)
        self.rig = Rig(cfg, self.calibration)
        self.layout = TickLayout([m.name for m in cfg.rig.muscles])
        self.sink = SummarySink(self.layout)
        self.ctrl = RigController(cfg, self.rig, self.sink, self.calibration)
        self.clock = VirtualClock()
        self.rig.open(self.clock)
        self.ctrl.start(0.0)
        self.t = 0.0
        self.records: list[dict[str, Any]] = []
        self.keep = False

    @property
    def sim(self) -> Any:
        return self.rig.drivers["sim"]

    @property
    def m1(self) -> Any:
        return self.ctrl.muscles[0]

    def step(self, seconds: float) -> None:
        for _ in range(round(seconds / self.period_s)):
            self.clock.t = self.t
            rec = self.ctrl.tick(self.t, self.period_s)
            self.sink.put(rec)
            if self.keep:
                self.records.append(self.layout.as_dict(rec))
            self.t += self.period_s

    def cmd(self, verb: str, **payload: Any) -> dict[str, Any]:
        return apply_command(self.ctrl, parse_command(verb, payload))

    @property
    def state(self) -> str:
        return self.ctrl.supervisor.state.name


@pytest.fixture
def harness(sim_config: Callable[..., LoadedConfig]) -> Iterator[Callable[..., Harness]]:
    made: list[Harness] = []

    def make(load_kg: float = 30.0, **changes: Any) -> Harness:
        h = Harness(sim_config(load_kg, **changes))
        made.append(h)
        return h

    yield make
    for h in made:
        h.rig.close()


@pytest.fixture
def sim_daemon(sim_config: Callable[..., LoadedConfig]) -> Iterator[Callable[..., Daemon]]:
    made: list[Daemon] = []

    def make(load_kg: float = 30.0, duration_s: float | None = None, **changes: Any) -> Daemon:
        d = Daemon(sim_config(load_kg, **changes))
        d.start(duration_s)
        made.append(d)
        return d

    yield make
    for d in made:
        d.stop("test finished")
        d.wait(timeout_s=30)
        d.close()

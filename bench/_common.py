"""Shared helpers for the benchmarks: the simulated rig config, a tick harness."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import copy  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import yaml  # noqa: E402

from pamd.config import LoadedConfig, load_config  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def sim_config(clock: str = "virtual", load_kg: float = 30.0, realtime: bool = False,
               **changes: Any) -> LoadedConfig:
    """config/sim.yaml with the given clock and load, written to a temp dir."""
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["loop"]["clock"] = clock
    data["loop"]["realtime"] = {"enabled": realtime}
    data["drivers"][0]["options"]["muscles"][0]["load_kg"] = load_kg
    data["muscles"][0]["load_kg"] = load_kg
    for section, values in changes.items():
        if isinstance(values, dict) and isinstance(data.get(section), dict):
            merged = copy.deepcopy(data[section])
            merged.update(values)
            data[section] = merged
        else:
            data[section] = values
    path = Path(tempfile.mkdtemp(prefix="pamd-bench-")) / "sim.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return load_config(str(path))


def percentile(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q / 100 * len(s)))]

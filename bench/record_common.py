"""Shared helpers of the recording benchmarks: a simulated rig config in a temp dir."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

from pamd.config import LoadedConfig, load_config

SIM_YAML = Path(__file__).resolve().parents[1] / "config" / "sim.yaml"


def sim_dict(clock: str = "virtual", muscles: int = 1, realtime: bool = False,
             recording: dict[str, Any] | None = None) -> dict[str, Any]:
    base = yaml.safe_load(SIM_YAML.read_text())
    base["loop"]["clock"] = clock
    base["loop"]["realtime"] = {"enabled": realtime}
    if muscles > 1:
        sm = base["drivers"][0]["options"]["muscles"][0]
        m0 = base["muscles"][0]
        base["drivers"][0]["options"]["muscles"] = []
        base["muscles"] = []
        for k in range(muscles):
            name = f"m{k + 1}"
            s = copy.deepcopy(sm)
            s["name"] = name
            base["drivers"][0]["options"]["muscles"].append(s)
            m = copy.deepcopy(m0)
            m["name"] = name
            for sig in m["signals"].values():
                sig["channel"] = sig["channel"].replace("m1.", f"{name}.")
            base["muscles"].append(m)
    if recording:
        base["recording"] = recording
    return base


def sim_config(tmp: str, **kw: Any) -> LoadedConfig:
    path = Path(tmp) / "bench.yaml"
    path.write_text(yaml.safe_dump(sim_dict(**kw), sort_keys=False))
    return load_config(str(path))


def write_config(tmp: str, **kw: Any) -> str:
    path = Path(tmp) / "bench.yaml"
    path.write_text(yaml.safe_dump(sim_dict(**kw), sort_keys=False))
    return str(path)

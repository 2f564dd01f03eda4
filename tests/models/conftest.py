"""Shared set-up for the model-kind tests: single-threaded BLAS and a few short
recorded pressure sweeps at several loads (virtual clock, a few seconds in all)."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: threaded BLAS is slower

from pathlib import Path  # noqa: E402

import pytest  # noqa: E402
import yaml  # noqa: E402

from pamd.client.cli.main import main  # noqa: E402
from pamd.config import load_config  # noqa: E402
from pamd.daemon.daemon import Daemon  # noqa: E402
from pamd.daemon.io_session import RecordingRequest  # noqa: E402
from tests.once import once_per_run  # noqa: E402

SIM_YAML = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"
SWEEP_LOADS_KG = (20.0, 40.0, 60.0)


def record_sweep(tmp: Path, load_kg: float, lo: float = 0.5, hi: float = 5.5,
                 freq_hz: float = 0.1, cycles: int = 2) -> Path:
    """One recorded sine pressure sweep at `load_kg` under PID pressure control."""
    data = yaml.safe_load(SIM_YAML.read_text())
    data["loop"]["clock"] = "virtual"
    data["loop"]["realtime"] = {"enabled": False}
    data["telemetry"] = {"enabled": False}
    data["drivers"][0]["options"]["muscles"][0]["load_kg"] = load_kg
    data["muscles"][0]["load_kg"] = load_kg
    cfg_path = tmp / f"sim{load_kg:g}.yaml"
    cfg_path.write_text(yaml.safe_dump(data, sort_keys=False))
    d = Daemon(load_config(str(cfg_path)),
               recording=RecordingRequest(dir=str(tmp), run_name=f"sweep{load_kg:g}kg"))
    pending = d.submit("profile", {"kind": "sine", "min_bar": lo, "max_bar": hi,
                                   "freq_hz": freq_hz, "cycles": cycles})
    d.start(stop_when_profile_done=True)
    try:
        assert pending.result(30.0)["ok"]
        d.wait(timeout_s=120)
    finally:
        d.stop("done")
        d.wait(timeout_s=60)
        d.close()
    return Path(d.result()["recording"]["files"][0])


@pytest.fixture(scope="session")
def sweeps(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """0.1 Hz 0.5-5.5 bar sweeps, 2 cycles each, at 20, 40 and 60 kg (recorded once
    per run: tests/once.py)."""
    def build(tmp: Path) -> list[str]:
        return [str(record_sweep(tmp, load)) for load in SWEEP_LOADS_KG]

    return [Path(p) for p in once_per_run(tmp_path_factory, "sweeps", build)]


@pytest.fixture(scope="session")
def trained(sweeps: list[Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One model file per kind, trained by `pamd train --kind` on the sweeps (small
    settings: seconds; trained once per run: tests/once.py)."""
    def build(out: Path) -> dict[str, str]:
        return {kind: str(path) for kind, path in train_each_kind(sweeps, out).items()}

    return {kind: Path(p) for kind, p in
            once_per_run(tmp_path_factory, "trained", build).items()}


def train_each_kind(sweeps: list[Path], out: Path) -> dict[str, Path]:
    runs = [str(p) for p in sweeps]
    args = {
        "anfis": ["--epochs", "20", "--mfs", "3"],
        "ts-fuzzy": ["--tuner", "mga", "--epochs", "4", "--population", "16"],
        # fits worse than a constant on these 2 s validation blocks (NRMSE fit -15.7 %):
        # refused by default since #28; the tests need a file of the kind all the same
        "polynomial": ["--allow-poor-fit"],
        "sarosi": [],
    }
    paths = {}
    for kind, extra in args.items():
        path = out / f"{kind}.json"
        assert main(["train", *runs, "--out", str(path), "--kind", kind, "--quiet",
                     "--block-s", "2", *extra]) == 0, kind
        paths[kind] = path
    return paths

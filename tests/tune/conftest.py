"""The on/off step test of config/sim-onoff.yaml's m1, run once per test run (virtual
clock: the same every time; tests/once.py shares it between the xdist workers) for the
tests that only read what it measured."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

from pamd.client.tune.onoff_run import run_onoff
from pamd.client.tune.onoff_steps import StepTest
from tests.once import once_per_run

REPO = Path(__file__).resolve().parents[2]
ONOFF = REPO / "config" / "sim-onoff.yaml"


def _step_test(into: Path) -> dict[str, str]:
    test = run_onoff(str(ONOFF), "virtual", "m1", str(into / "run"))
    (into / "test.pickle").write_bytes(pickle.dumps(test))
    return {"run": str(into / "run"), "test": str(into / "test.pickle")}


@pytest.fixture(scope="session")
def onoff_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[StepTest, Path]:
    """The step test of m1 on config/sim-onoff.yaml (what the analysis returned, with
    each pulse's trace) and the directory of its recording."""
    built = once_per_run(tmp_path_factory, "onoff-step-test", _step_test)
    test = pickle.loads(Path(built["test"]).read_bytes())
    assert isinstance(test, StepTest)
    return test, Path(built["run"])

"""On/off valves in mode position (issue #25 item 7): seed 004's sliding mode moves the
valves on the length alone, so a model is refused there with the reason (not accepted
and left unused), and the muscle has no pressure setpoint meanwhile: the record's
`setpoint_bar` is NaN and the summary's pressure tracking is null, not 0.0000 bar."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pamd.config import LoadedConfig
from pamd.loop.control.feedforward import LoadedModel
from pamd.loop.control.onoff import POSITION_TAKES_NO_MODEL
from pamd.loop.harness import Harness
from pamd.wire.tick import M_SETPOINT
from tests.safety.conftest import onoff_muscles, sim_driver

REPO = Path(__file__).resolve().parents[2]


def onoff_config(sim_config: Callable[..., LoadedConfig]) -> LoadedConfig:
    return sim_config(30.0, drivers=sim_driver(30.0, 3.0, None, "onoff"),
                      muscles=onoff_muscles(30.0))


def test_position_mode_with_a_model_is_refused_with_the_reason(
        sim_config: Callable[..., LoadedConfig], static_model: Path) -> None:
    cfg = onoff_config(sim_config)
    h = Harness(cfg, {"m1": LoadedModel.read(str(static_model), cfg.muscle("m1"),
                                             cfg.limits["m1"])})
    try:
        h.step(1.0)
        v = h.cmd("mode", muscle="m1", mode="position")  # feedforward: true by default
        assert not v["ok"] and "sliding mode" in v["error"] and "feedforward" in v["error"]
        assert h.m1.mode.name == "PRESSURE"  # nothing changed
        # the model serves length_force, where the valves' PWM follows its pressure
        assert h.cmd("mode", muscle="m1", mode="length_force")["ok"]
    finally:
        h.rig.close()


def test_positioning_has_no_pressure_setpoint_and_no_pressure_tracking(
        sim_config: Callable[..., LoadedConfig]) -> None:
    h = Harness(onoff_config(sim_config))
    try:
        h.step(1.0)
        assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
        assert h.cmd("profile", muscle="m1", kind="sine", min_contraction=0.08,
                     max_contraction=0.14, freq_hz=0.1, cycles=1)["ok"]
        h.step(12.0)
        assert math.isnan(h.ctrl.record[h.m1._base + M_SETPOINT])  # noqa: SLF001
        t = h.sink.tracking()["m1"]
        assert t["rmse_bar"] is None and t["max_error_bar"] is None and t["samples"] == 0
        assert t["length_samples"] > 5000 and t["length_rmse_mm"] is not None
        assert 0.0 < t["length_rmse_mm"] < 2.0
        # back in pressure mode the setpoint is recorded again
        assert h.cmd("mode", muscle="m1", mode="pressure")["ok"]
        h.step(0.1)
        assert not math.isnan(h.ctrl.record[h.m1._base + M_SETPOINT])  # noqa: SLF001
    finally:
        h.rig.close()


def test_pamd_run_refuses_a_model_for_onoff_positioning_before_anything_opens(
        pamd_here: Callable[..., Any], static_model: Path) -> None:
    r = pamd_here("run", "--config", REPO / "config" / "sim-onoff.yaml", "--clock", "virtual",
                  "--mode", "position", "--model", static_model, "--profile", "sine",
                  "--min-contraction", "0.08", "--max-contraction", "0.14", "--cycles", "1",
                  "--no-telemetry", "--no-record")
    assert r.returncode == 4, r
    assert POSITION_TAKES_NO_MODEL in r.stderr and "m1: --mode position" in r.stderr
    assert "ticks" not in r.stdout  # no run, no summary


def test_pamd_run_onoff_positioning_summary_has_null_pressure_tracking(
        pamd_here: Callable[..., Any], tmp_path: Path) -> None:
    args = ["run", "--config", REPO / "config" / "sim-onoff.yaml", "--clock", "virtual",
            "--mode", "position", "--no-feedforward", "--profile", "sine", "--freq-hz", "0.1",
            "--min-contraction", "0.08", "--max-contraction", "0.14", "--cycles", "1",
            "--no-telemetry", "--no-record", "--state-dir", tmp_path]
    r = pamd_here(*args, "--json")
    assert r.returncode == 0, r
    t = json.loads(r.stdout)["tracking"]["m1"]
    assert t["rmse_bar"] is None and t["max_error_bar"] is None and t["samples"] == 0
    assert t["length_rmse_mm"] is not None and t["length_samples"] > 0
    r = pamd_here(*args)
    assert r.returncode == 0, r
    assert "pressure tracking" not in r.stdout and "length tracking RMSE" in r.stdout

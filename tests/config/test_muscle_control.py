"""Per-muscle gains (`muscles[].control`): each key overrides the rig-wide one of the
same name, the rest fall back; unknown keys are refused with file and line; the
muscle's pressure loop and position PID run on them; a reload applies them at once."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from pamd.config import LoadedConfig
from pamd.daemon.service.reload import classify, plan_reload
from pamd.wire.errors import ConfigError

from ..conftest import sim_dict


def _own(**control: Any) -> dict[str, Any]:
    d = sim_dict()
    d["muscles"][0]["control"] = control
    return d


def test_a_muscle_overrides_some_gains_and_keeps_the_rest(
        sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = sim_config(muscles=_own(pid={"kp": 0.3}, rate_feedforward_s=0.04,
                                  position={"pid": {"ki_bar_per_mm_s": 1.0}})["muscles"])
    rig, own = cfg.rig.control, cfg.control_of("m1")
    assert (own.pid.kp, own.pid.ki_per_s) == (0.3, rig.pid.ki_per_s)
    assert own.pid.integral_limit_bar == rig.pid.integral_limit_bar
    assert own.rate_feedforward_s == 0.04 != rig.rate_feedforward_s
    assert own.position.pid.ki_bar_per_mm_s == 1.0
    assert own.position.pid.kp_bar_per_mm == rig.position.pid.kp_bar_per_mm
    assert own.slew_limit_bar_per_s == rig.slew_limit_bar_per_s
    # none set: the rig's section itself
    plain = sim_config()
    assert plain.control_of("m1") is plain.rig.control


def test_unknown_or_bad_keys_are_refused_with_file_and_line(
        sim_config: Callable[..., LoadedConfig]) -> None:
    with pytest.raises(ConfigError) as exc:
        sim_config(muscles=_own(pid={"kq": 0.3})["muscles"])
    msg = str(exc.value)
    assert "sim.yaml:" in msg and "muscles[0].control.pid.kq" in msg
    with pytest.raises(ConfigError, match=r"muscles\[0\]\.control\.rate_feedforward_s"):
        sim_config(muscles=_own(rate_feedforward_s=-1.0)["muscles"])


def test_the_muscle_runs_on_its_own_gains(harness: Any) -> None:
    h = harness(muscles=_own(pid={"kp": 0.3}, position={"pid": {"kp_bar_per_mm": 0.02}})[
        "muscles"])
    assert h.m1.pressure_loop.pid.kp == 0.3
    assert h.m1.pressure_loop.pid.ki == h.cfg.rig.control.pid.ki_per_s
    assert h.m1.length_control.pid.kp == 0.02


def test_a_reload_applies_a_muscles_gains_at_once(
        sim_config: Callable[..., LoadedConfig]) -> None:
    assert classify("muscles[0].control.pid.kp") == "now"
    assert classify("muscles[0].control.rate_feedforward_s") == "now"
    assert classify("muscles[0].control.position.pid.kp_bar_per_mm") == "restart"
    old = sim_config()
    new = sim_config(muscles=_own(pid={"kp": 0.3})["muscles"])
    plan = plan_reload(old, old, old, new)
    assert plan.now == ["muscles[0].control.pid.kp"] and not plan.restart
    assert plan.args.plan[0].pid.kp == 0.3

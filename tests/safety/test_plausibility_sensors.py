"""Realistic healthy sensors raise no fault (issue 23): quantised (16 bit), slow (10
samples/s), noiseless, filtered, bursty, and a noiseless load cell under a dead weight,
each for a minute of virtual time of a slow full-range sine (the muscle moving all the
while). The premise that used to fault (`m1.force frozen at 294.3 N for 202 ms while the
muscle moved: stuck sensor`) is asserted to occur, so the test would catch that check
coming back. The other half, each dead or stuck sensor still found in its stated time
on such sensors, is test_plausibility.py's table on config/sim-harsh.yaml."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from ..conftest import sim_dict
from .conftest import SafetyRig, sensor_signals, sim_driver

ADC16 = {"pressure_adc_bits": 16, "force_adc_bits": 16, "pressure_noise_bar": 0.0,
         "force_noise_n": 0.0}
#: name -> (sim muscle options, the rig's signal settings that fit them, load kg)
SENSORS: dict[str, tuple[dict[str, Any], dict[str, dict[str, float]], float]] = {
    "quantised-16bit": (ADC16, {}, 30.0),
    "10-samples-per-s": ({**ADC16, "pressure_sample_period_s": 0.1,
                          "force_sample_period_s": 0.1},
                         {"pressure": {"sample_period_s": 0.1, "timeout_s": 0.2},
                          "force": {"sample_period_s": 0.1, "timeout_s": 0.2}}, 30.0),
    "noiseless": ({"pressure_noise_bar": 0.0, "force_noise_n": 0.0}, {}, 30.0),
    "filtered": ({"pressure_filter_s": 0.02, "force_filter_s": 0.05, "length_filter_s": 0.005},
                 {}, 30.0),
    "bursty": ({"pressure_burst_s": 0.04, "force_burst_s": 0.04, "length_burst_s": 0.04,
                "burst_every_s": 0.5},
               {"pressure": {"timeout_s": 0.08}, "force": {"timeout_s": 0.08},
                "length": {"timeout_s": 0.08}}, 30.0),
    "dead-weight-load-cell": (ADC16, {}, 80.0),
}
MINUTE_S = 60.0
#: where the old false alarm's premise is asserted to occur (a load cell repeating one
#: value for frozen_s while the muscle moved 0.5 mm)
PREMISE = ("quantised-16bit", "dead-weight-load-cell")


@pytest.mark.parametrize("name", list(SENSORS))
def test_a_realistic_healthy_sensor_raises_no_fault_in_a_minute_of_motion(
        safety_rig: Callable[..., SafetyRig], name: str) -> None:
    rig = safety_rig_for(safety_rig, name)
    h = rig.h
    load = SENSORS[name][2]
    low = 1.6 if load > 50 else 0.0
    h.step(0.01)
    h.cmd("profile", kind="sine", min_bar=low, max_bar=6.0, freq_hz=0.05, cycles=3)
    drv = h.sim
    fi, li = drv.input_index("m1.force"), drv.input_index("m1.length")
    frozen_s = h.cfg.rig.safety.plausibility.frozen_s
    last_f, since, l0 = drv.in_values[fi], h.t, drv.in_values[li]
    premise = False  # the force identical for frozen_s while the muscle moved 0.5 mm
    if name not in PREMISE:
        h.step(MINUTE_S)
    for _ in range(round(MINUTE_S / h.period_s) if name in PREMISE else 0):
        h.step(h.period_s)
        f, length = drv.in_values[fi], drv.in_values[li]
        if f != last_f:
            last_f, since, l0 = f, h.t, length
        elif h.t - since >= frozen_s and abs(length - l0) >= 0.5:
            premise = True
    assert h.ctrl.supervisor.faults == [], h.ctrl.supervisor.fault_reason
    assert not [e for e in h.sink.events if e[1] == "implausible"]
    assert h.state == "RUNNING"  # still going: three 20 s cycles
    if name in PREMISE:
        assert premise, "the load cell never held one value while the muscle moved"


def safety_rig_for(make: Callable[..., SafetyRig], name: str) -> SafetyRig:
    """The safety rig with sensor set `name` and the rig's signal settings for it."""
    options, signals, load = SENSORS[name]
    sigs = sensor_signals("sim")
    for sig, changes in signals.items():
        sigs[sig].update(changes)
    m = sim_dict(load)["muscles"][0]
    m["signals"] = sigs
    initial = 1.6 if load > 50 else 0.0
    return make(load, initial, drivers=sim_driver(load, initial, **options), muscles=[m])

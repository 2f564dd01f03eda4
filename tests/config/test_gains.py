"""Gains judged against stability (issue 47, item 1): each loop's gains on the muscle's
identified plant, as the tick runs them (discrete, at the loop's rate); timing keys
bounded by physics; and the config smalls of item 4 (the model file cap declared once,
a nominal length refused under its own key)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pamd.config import LoadedConfig, load_config_text
from pamd.config.control_schema import DEFAULT_PRESSURE_PLANT
from pamd.config.schema import MODEL_FILE_MAX_BYTES
from pamd.config.stability import (
    REFUSE_GAIN_MARGIN,
    Plant,
    incremental,
    margins,
    pid,
    sampled_plant,
)
from pamd.daemon.service.reload import classify
from pamd.loop.harness import Harness
from pamd.models.registry import MAX_FILE_BYTES
from pamd.wire.errors import ConfigError

from ..conftest import sim_dict

REPO = Path(__file__).resolve().parents[2]
SIM = (REPO / "config" / "sim.yaml").read_text()
PLANT = Plant(DEFAULT_PRESSURE_PLANT.gain_bar_per_bar, DEFAULT_PRESSURE_PLANT.lag_s,
              DEFAULT_PRESSURE_PLANT.dead_time_s)
#: seed 003's Table 3, Method 1 (its own muscle and units): Kp 9.5, Ki 1.3, Kd 0.5
SEED_003 = {"method": 1, "kp_bar_per_mm": 9.5, "ki_bar_per_mm": 1.3, "kd_bar_per_mm": 0.5}


def text(**changes: Any) -> str:
    return yaml.safe_dump(sim_dict(**changes), sort_keys=False)


def issues(**changes: Any) -> list[Any]:
    with pytest.raises(ConfigError) as exc:
        load_config_text(text(**changes), "rig.yaml")
    return exc.value.issues


def loads(**changes: Any) -> LoadedConfig:
    return load_config_text(text(**changes), "rig.yaml")


# -- the judgement itself ----------------------------------------------------------------


def test_the_sampled_plant_is_the_fopdt_step_response_at_the_ticks() -> None:
    """The modified z-transform: the difference equation's step response equals the
    continuous model's at every tick, for a dead time between ticks too."""
    for plant in (PLANT, Plant(0.95, 0.0125, 0.0120), Plant(6.6, 0.0316, 0.0362)):
        num, den = sampled_plant(plant, 1e-3)
        u = np.ones(200)
        y = np.zeros(200)
        for k in range(200):
            acc = sum(c * u[k - i] for i, c in num.items() if k - i >= 0)
            y[k] = acc - (den.get(1, 0.0) * y[k - 1] if k else 0.0)
        t = np.arange(200) * 1e-3 - plant.dead_time_s
        want = np.where(t > 0, plant.gain * (1.0 - np.exp(-t / np.maximum(plant.lag_s,
                                                                           1e-12))), 0.0)
        np.testing.assert_allclose(y, want, atol=1e-12)


def test_a_pure_gain_and_one_tick_of_delay_has_its_textbook_margin() -> None:
    """L = K z^-1 (no lag, no dead time: the zero-order hold's tick) closes to a pole at
    -K: stable below K = 1, gain margin 1/K."""
    plant = Plant(1.0, 1e-9, 0.0)
    for k, stable in ((0.5, True), (0.9, True), (1.2, False)):
        m = margins(pid(k, 0.0, 0.0, 30.0, 1e-3), plant, 1e-3)
        assert m.stable is stable and m.gain_margin == pytest.approx(1.0 / k, rel=1e-3)


def test_the_winding_test_agrees_with_the_closed_loops_roots() -> None:
    """The argument principle (pure Python, no numpy where the loader is imported) says
    stable exactly where every root of the characteristic polynomial is inside the unit
    circle, over gains across the boundary, plants and rates."""
    rng = np.random.default_rng(47)
    for _ in range(60):
        plant = Plant(float(rng.uniform(0.2, 8.0)), float(rng.uniform(0.002, 0.05)),
                      float(rng.uniform(0.0, 0.04)))
        period = float(rng.choice([1e-3, 2e-3, 1e-2]))
        kp, ki = float(rng.uniform(0.0, 2.0)), float(rng.uniform(0.0, 300.0))
        kd = float(rng.choice([0.0, 1e-3]))
        num, den = pid(kp, ki, kd, 30.0, period)
        gn, gd = sampled_plant(plant, period)
        char: dict[int, float] = {}
        for a, b in ((num, gn), (den, gd)):
            for i, x in a.items():
                for j, y in b.items():
                    char[i + j] = char.get(i + j, 0.0) + x * y
        coefficients = [char.get(k, 0.0) for k in range(max(char) + 1)]
        roots = np.roots(coefficients)  # z^N P(1/z): the same coefficients, descending
        if abs(np.abs(roots).max() - 1.0) < 1e-6:
            continue  # on the circle: either answer is a refusal by the margins
        want = bool(np.abs(roots).max() < 1.0)
        assert margins((num, den), plant, period).stable is want, (plant, period, kp, ki)


@pytest.mark.parametrize("kp, ki, oscillates", [
    (0.516, 41.2, False),  # the shipped gains: gain margin 2.97, phase margin 61 deg
    (0.516, 150.0, True),  # judged unstable: gain margin 0.78
    (2.2, 41.2, True),  # judged unstable: gain margin 0.98
])
def test_the_judgement_foretells_the_rigs_oscillation(
        harness: Callable[..., Harness], kp: float, ki: float, oscillates: bool) -> None:
    """On the simulated rig, at a 3 bar setpoint: the gains judged unstable limit-cycle
    (the pressure swings by tenths of a bar), those judged stable hold within the
    sensor's noise. The unstable ones run only with `safety.relax_stability`."""
    m = margins(pid(kp, ki, 0.0, 30.0, 1e-3), PLANT, 1e-3)
    assert m.stable is not oscillates and m.refused() is oscillates
    h = harness(control={"pid": {"kp": kp, "ki_per_s": ki}},
                safety={"relax_stability": True})
    h.keep = True
    assert h.cmd("setpoint", muscle="m1", bar=3.0)["ok"]
    h.step(2.0)
    p = np.array([r["m1"]["pressure_bar"] for r in h.records[-800:]])
    swing = float(p.std())
    assert (swing > 0.1 if oscillates else swing < 0.01), swing


POSITION_PID = "control.position.pid"


def _position_swing(h: Harness) -> float:
    """The position loop (PID alone) at 10 % contraction, then a 4 mm step of the
    target: the length's rms swing over the last second after it."""
    h.keep = True
    h.step(0.5)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    assert h.cmd("profile", muscle="m1", kind="constant", to_contraction=0.1,
                 duration_s=3)["ok"]
    h.step(3.0)
    assert h.cmd("profile", muscle="m1", kind="constant", to_contraction=0.12,
                 duration_s=10)["ok"]
    h.step(3.0)
    return float(np.array([r["m1"]["length_mm"] for r in h.records[-1000:]]).std())


@pytest.mark.parametrize("kp, ki, oscillates", [
    (0.0656, 12.0, False),  # judged unstable on the fit by its integral: warned
    (0.5, 2.08, True),  # its proportional part alone unstable: refused
])
def test_the_position_loops_integral_is_warned_where_friction_holds_the_muscle(
        harness: Callable[..., Harness], kp: float, ki: float, oscillates: bool) -> None:
    """The position plant is a fit of sliding 0.5 bar steps; near its target a muscle
    held by friction moves a fraction of that per bar, where the integral acts
    (pamd.config.gains). An integral judged unstable on the fit holds the length and
    tracks a 4 mm step: it loads, warned, naming both verdicts; a proportional gain
    unstable on its own limit-cycles on the rig and stays refused."""
    gains = {"kp_bar_per_mm": kp, "ki_bar_per_mm_s": ki}
    if oscillates:
        (issue,) = issues(control={"position": {"pid": gains}})
        assert issue.path == POSITION_PID and "UNSTABLE" in issue.found
    else:
        (warning,) = loads(control={"position": {"pid": gains}}).warnings
        assert f"{POSITION_PID}: kp_bar_per_mm 0.0656, ki_bar_per_mm_s 12" in warning
        assert "UNSTABLE: gain margin 0.458" in warning, warning
        assert "by its integral: without it gain margin 4.74" in warning, warning
        assert "friction" in warning and "limit cycle" in warning
    h = harness(control={"position": {"pid": gains}}, safety={"relax_stability": True})
    swing = _position_swing(h)
    assert (swing > 0.1 if oscillates else swing < 0.02), swing


def test_only_the_position_loop_and_only_its_integral_is_judged_so() -> None:
    """The pressure loop's verdicts stand (no friction in the regulator's air); seed
    003's Method 2 splits its Ki off like the PID; a position integral with a thin
    proportional part is refused on that part."""
    (issue,) = issues(control={"pid": {"ki_per_s": 150.0}})
    assert issue.path == "control.pid" and "UNSTABLE" in issue.found
    (issue,) = issues(control={"position": {"pid": {"kp_bar_per_mm": 0.25,
                                                    "ki_bar_per_mm_s": 8.0}}})
    assert issue.path == POSITION_PID  # kp 0.25 alone: gain margin under 1.5
    m2 = {"feedback": "incremental", "incremental": {
        "method": 2, "kp_bar_per_mm": 0.0656, "ki_bar_per_mm": 0.012, "kd_bar_per_mm": 0.0}}
    (warning,) = loads(control={"position": m2}).warnings
    assert "control.position.incremental" in warning and "by its integral" in warning
    cfg = loads(control={"position": {"pid": {"ki_bar_per_mm_s": 12.0}}})
    from pamd.config.gains import loop_margins

    (_, pressure, _), (_, position, _) = loop_margins(cfg.rig, 0)
    assert pressure.outcome == "ok" and position.outcome == "integral"
    assert "warned, not refused: friction" in position.note()


# -- refused, warned, accepted ------------------------------------------------------------


def test_gains_that_oscillate_inside_the_caps_are_refused_naming_the_margins() -> None:
    """The issue's kp 19.9, ki 1999 (inside the caps): refused at control.pid's line,
    naming the margins, the plant and the gains SIMC derives on it."""
    (issue,) = issues(control={"pid": {"kp": 19.9, "ki_per_s": 1999.0}})
    assert issue.path == "control.pid"
    assert "UNSTABLE: gain margin 0.0657" in issue.found and "kp 19.9" in issue.found
    assert "default plant" in issue.expected and "lag 12.5 ms" in issue.expected
    assert "SIMC on it gives kp 0.514, ki_per_s 41.1" in issue.expected
    (issue,) = issues(control={"pid": {"ki_per_s": 400.0}})  # ki alone: 1.48 bar, unsafe
    assert issue.path == "control.pid" and "UNSTABLE" in issue.found
    # a margin too thin to run on: stable on the stated plant, refused
    (issue,) = issues(control={"pid": {"ki_per_s": 100.0}})
    assert "UNSTABLE" not in issue.found and "gain margin 1.27" in issue.found
    assert f"at least {REFUSE_GAIN_MARGIN:g}" in issue.expected


def test_the_shipped_gains_load_quietly_and_a_thin_margin_is_warned() -> None:
    assert loads().warnings == ()
    cfg = loads(control={"pid": {"kp": 1.0}})  # gain margin 1.96: rings
    (warning,) = cfg.warnings
    assert "control.pid: kp 1, ki_per_s 41.2" in warning and "gain margin 1.96" in warning


def test_a_measured_plant_is_what_the_gains_are_judged_on() -> None:
    """Gains stable on the default plant but not on a slower one (a longer hose: 40 ms
    dead time) are refused once that plant is stated; the same plant per muscle."""
    slow = {"gain_bar_per_bar": 0.95, "lag_s": 0.02, "dead_time_s": 0.04}
    (issue,) = issues(control={"plant": slow})
    assert issue.path == "control.pid" and "(control.plant)" in issue.expected
    muscle = sim_dict()["muscles"][0]
    (issue,) = issues(muscles=[{**muscle, "control": {"plant": slow}}])
    assert "(muscles[0].control.plant)" in issue.expected
    # ... and its own gains, judged on it, are refused under its own key
    (issue,) = issues(muscles=[{**muscle, "control": {"pid": {"kp": 3.0}}}])
    assert issue.path == "muscles[0].control.pid" and issue.line is not None
    loads(control={"plant": slow, "pid": {"kp": 0.25, "ki_per_s": 10.0}})


def test_a_plant_changes_at_once_on_a_reload() -> None:
    """No tick reads a plant: a reload that states one (after `pamd tune --save`) needs
    no restart, and its gains are judged against it as the new config loads."""
    for path in ("control.plant.lag_s", "muscles[1].control.position.plant.lag_s"):
        assert classify(path) == "now"


def test_a_refused_loop_loads_with_the_named_override_and_says_so() -> None:
    cfg = loads(control={"pid": {"ki_per_s": 400.0}}, safety={"relax_stability": True})
    (warning,) = cfg.warnings
    assert "UNSTABLE" in warning and "safety.relax_stability is true" in warning


def test_check_config_and_the_daemon_refuse_unstable_gains(tmp_path: Path,
                                                            pamd_here: Any) -> None:
    r = pamd_here("check-config", REPO / "config" / "sim.yaml")
    assert r.returncode == 0 and "pressure loop: gain margin 2.97" in r.stdout
    assert "position loop: gain margin 3.1" in r.stdout
    path = tmp_path / "rig.yaml"
    path.write_text(text(control={"pid": {"kp": 19.9, "ki_per_s": 1999.0}}))
    for args in (("check-config", path), ("run", "--config", path, "--duration", "1")):
        r = pamd_here(*args)
        assert r.returncode == 2 and "control.pid" in r.stderr and "gain margin" in r.stderr
        assert "Traceback" not in r.stderr


def test_seed_003s_gains_are_judged_on_the_plant_not_capped() -> None:
    """Method 1's Kp 9.5 (once refused by a cap of 5 bar/mm) is judged like any gain: on
    the simulated DMSP-20-200 (-6.6 mm/bar) its Ki 1.3 bar/mm is a proportional loop
    gain of 8.6: refused as unstable; on a stiff muscle that moves 0.05 mm per bar,
    sampled every 10 ms, it is stable and loads."""
    incremental_ = {"feedback": "incremental", "incremental": SEED_003}
    (issue,) = issues(control={"position": incremental_})
    assert issue.path == "control.position.incremental"
    assert "method 1, Kp 9.5, Ki 1.3, Kd 0.5" in issue.found and "UNSTABLE" in issue.found
    assert "at most" not in issue.expected  # no cap
    stiff = {"gain_mm_per_bar": -0.05, "lag_s": 0.0316, "dead_time_s": 0.0362}
    cfg = loads(control={"position": {
        "feedback": "incremental", "plant": stiff,
        "incremental": {**SEED_003, "sample_period_s": 0.01},
        "pid": {"kp_bar_per_mm": 5.0, "ki_bar_per_mm_s": 20.0}}})
    assert cfg.rig.control.position.incremental.kp_bar_per_mm == 9.5
    m = margins(incremental(1, 9.5, 1.3, 0.5), Plant(0.05, 0.0316, 0.0362), 0.01)
    assert m.stable and not m.warned()


def test_on_off_muscles_have_no_pid_to_judge() -> None:
    cfg = load_config_text((REPO / "config" / "sim-onoff.yaml").read_text(), "onoff.yaml")
    assert cfg.warnings == ()


# -- timing keys bounded by physics -------------------------------------------------------


@pytest.mark.parametrize("key, value, bound", [
    ("tracking_time_s", 1e-300, "at least 50.3 ms"),  # the plant's dead time + 3 lags
    ("tracking_time_s", 0.04, "at least 50.3 ms"),
    ("startup_timeout_s", 1e-300, "at least 50 ms"),  # first sample: the latency margin
    ("plausibility", {"frozen_s": 1e-300}, "at least 1 ms"),
    ("plausibility", {"force_zero_s": 1e-4}, "at least 1 ms"),
])
def test_timing_keys_shorter_than_their_physics_are_refused_under_their_key(
        key: str, value: Any, bound: str) -> None:
    (issue,) = issues(safety={key: value})
    path = f"safety.{key}" if not isinstance(value, dict) else \
        f"safety.{key}.{next(iter(value))}"
    assert issue.path == path and bound in issue.expected and issue.line is not None


def test_timing_keys_at_their_physics_load() -> None:
    loads(safety={"tracking_time_s": 0.06, "startup_timeout_s": 0.05,
                  "plausibility": {"frozen_s": 0.001, "force_zero_s": 0.001}})
    # the tracking bound follows the stated plant: a slower one needs longer
    slow = {"gain_bar_per_bar": 0.95, "lag_s": 0.02, "dead_time_s": 0.04}
    (issue,) = issues(control={"plant": slow, "pid": {"kp": 0.25, "ki_per_s": 10.0}},
                      safety={"tracking_time_s": 0.06})
    assert issue.path == "safety.tracking_time_s" and "at least 100 ms" in issue.expected


@pytest.mark.parametrize("changes, path", [
    ({"loop": {"stall_fault_s": 1e-300}}, "loop.stall_fault_s"),
    ({"control": {"position": {"ilc": {"resolution_s": 1e-300}}}},
     "control.position.ilc.resolution_s"),
    ({"control": {"position": {"incremental": {"sample_period_s": 1e-5}}}},
     "control.position.incremental.sample_period_s"),
])
def test_durations_below_a_tick_are_refused(changes: dict[str, Any], path: str) -> None:
    (issue,) = issues(**changes)
    assert issue.path == path and "ticks at loop.rate_hz 1000" in issue.expected


# -- item 4: the config smalls ------------------------------------------------------------


def test_a_nominal_length_of_a_micrometre_is_refused_under_its_own_key() -> None:
    muscle = sim_dict()["muscles"][0]
    (issue,) = issues(muscles=[{**muscle, "nominal_length_mm": 1e-3}])
    assert issue.path == "muscles[0].nominal_length_mm"
    assert "at least 10.0 mm" in issue.expected and "slip of units" in issue.expected
    loads(muscles=[{**muscle, "nominal_length_mm": 60.0}])  # a dmsp20 is made from 60 mm


def test_the_model_file_cap_is_declared_once_and_documented_as_enforced() -> None:
    assert MAX_FILE_BYTES == MODEL_FILE_MAX_BYTES
    reference = (REPO / "docs" / "config-reference.md").read_text()
    row = next(ln for ln in reference.splitlines() if "`telemetry.models_dir`" in ln)
    assert f"at most {MODEL_FILE_MAX_BYTES >> 20} MiB" in row
    assert math.log2(MODEL_FILE_MAX_BYTES) == 23  # 8 MiB, as every reader enforces

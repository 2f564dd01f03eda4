"""`pamd commission` on config/sim-harsh.yaml, the simulated rig read through the
field's worst sensors (16-bit noiseless inputs, a 10 samples/s load cell, a bursty
encoder link): it measures what they are, proposes thresholds that raise no false
fault over a minute (five with -m slow) and still find a dead sensor, and saves them keeping the
file's comments."""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import pytest

from pamd.config import load_config

from .conftest import LONG_SOAK_S, QUICK, SOAK_S, commission, copy_config, proposed
from .soak import finds, no_false_fault


@pytest.fixture(scope="module")
def harsh(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any], str]:
    """config/sim-harsh.yaml commissioned with --save (its copy), and the report."""
    path = copy_config("sim-harsh.yaml", tmp_path_factory.mktemp("harsh"))
    before = path.read_text()
    rc, report, err = commission(path, "--save", *QUICK)
    assert rc == 0, (err, report.get("refusals"))
    return path, report, before


def test_it_measures_the_sensors_as_they_are(harsh: tuple[Path, dict[str, Any], str]) -> None:
    _, report, _ = harsh
    sig = report["signals"]
    p, f, length = sig["m1.pressure"], sig["m1.force"], sig["m1.length"]
    # the sim's declared sensors: 100 and 10 samples/s, 16 bits over 10 bar and 4000 N
    assert p["period_s"] == pytest.approx(0.01, rel=1e-3)
    assert f["period_s"] == pytest.approx(0.1, rel=1e-3)
    assert p["quantum"] == pytest.approx(10.0 / 65535, rel=1e-3)
    assert f["quantum"] == pytest.approx(4000.0 / 65535, rel=1e-3)
    assert length["quantum"] == pytest.approx(0.01, rel=1e-3)
    assert p["noise"] == pytest.approx(0.0, abs=1e-9) and f["noise"] == pytest.approx(0.0,
                                                                                       abs=1e-9)
    # a 10 samples/s reading is up to a period old; the encoder's link holds 40 ms
    assert 0.09 <= f["worst_age_s"] <= 0.101
    assert 0.04 <= length["worst_age_s"] <= 0.045
    assert length["declared_jitter_s"] > 0.0  # stamped on arrival
    # the regulator's lag and the pressure input's 5 ms filter and 2 ms latency
    lat = [s["pressure_latency_s"] for s in report["steps"] if s["name"].startswith("up")]
    assert lat and all(0.005 < x < 0.1 for x in lat)
    assert report["ok"] and report["saved"]
    assert any("force reads 294" in c for c in report["checks"])


def test_the_proposals_follow_their_rules(harsh: tuple[Path, dict[str, Any], str]) -> None:
    _, report, _ = harsh
    rows = {r["key"]: r for r in report["thresholds"]}
    force = rows["muscles[m1].signals.force.timeout_s"]
    # max(2 x worst age, worst age + latency margin 0.05), up to 5 ms: 2 x 0.099 -> 0.2
    assert force["proposed"] == pytest.approx(0.2)
    assert force["margin"] == pytest.approx(force["present"] - force["measured"])
    length = rows["muscles[m1].signals.length.timeout_s"]
    assert length["proposed"] == pytest.approx(0.095)  # 0.041 + 0.05 -> 0.095
    assert not any(r["fires"] for r in report["thresholds"])
    jump = rows["safety.plausibility.pressure_jump_bar"]
    assert jump["proposed"] == pytest.approx(0.00062)  # 4 quanta of 0.15 mbar, 2 digits up
    assert rows["loop.stall_timeout_s"]["proposed"] is None  # not measured: virtual clock


def test_save_keeps_the_comments_and_loads(harsh: tuple[Path, dict[str, Any], str]) -> None:
    path, report, before = harsh
    after = path.read_text()
    comments = [ln for ln in before.splitlines() if ln.lstrip().startswith("#")]
    assert comments == [ln for ln in after.splitlines() if ln.lstrip().startswith("#")]
    cfg = load_config(str(path))
    prop = proposed(report)
    m1 = cfg.muscle("m1").signals
    assert m1.pressure.timeout_s == pytest.approx(prop["muscles[m1].signals.pressure.timeout_s"])
    assert m1.length.timeout_s == pytest.approx(0.095)
    pl = cfg.rig.safety.plausibility
    assert pl.length_jump_mm == pytest.approx(prop["safety.plausibility.length_jump_mm"])
    # in place: only the signal lines whose timeouts changed were rewritten (the
    # plausibility keys were added), nothing else
    removed = [ln for ln in difflib.ndiff(before.splitlines(), after.splitlines())
               if ln.startswith("- ")]
    assert removed and all("{driver: sim, channel: m1." in ln for ln in removed), removed
    assert "timeout_s: 0.095}  # 40 ms bursts" in after  # its comment kept


def test_the_proposed_thresholds_raise_no_false_fault(
        harsh: tuple[Path, dict[str, Any], str]) -> None:
    no_false_fault(harsh[0], SOAK_S)


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_the_proposed_thresholds_raise_no_false_fault_in_five_minutes(
        harsh: tuple[Path, dict[str, Any], str]) -> None:
    no_false_fault(harsh[0], LONG_SOAK_S)


@pytest.mark.parametrize(("signal", "kind"), [("force", "silent"), ("length", "silent"),
                                              ("pressure", "silent"), ("pressure", "dead"),
                                              ("length", "dead")])
def test_the_proposed_thresholds_still_find_a_dead_sensor(
        harsh: tuple[Path, dict[str, Any], str], signal: str, kind: str,
        tmp_path: Path) -> None:
    finds(harsh[0], harsh[1], signal, kind, tmp_path)

"""Datums that cannot lie (issue 11): `home` refused on an absolute sensor and
when it disagrees with the expected length; `tare` refused under an undeclared
load; both offline (`pamd home`, `pamd tare`) with the same rules."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.client.cli.main import main
from pamd.loop.devices.datum_file import load_calibration
from pamd.muscle_type import GRAVITY_M_S2, equilibrium_contraction, force_model

from .conftest import SafetyRig


def _incremental(load_kg: float, initial_bar: float = 0.0) -> list[dict[str, Any]]:
    return [{"name": "sim", "type": "sim", "options": {"seed": 1, "muscles": [
        {"name": "m1", "load_kg": load_kg, "initial_pressure_bar": initial_bar,
         "length_absolute": False}]}}]


def _signals(**length: Any) -> dict[str, Any]:
    sig: dict[str, Any] = {k: {"driver": "sim", "channel": f"m1.{k}"}
                           for k in ("pressure", "force", "length")}
    sig["length"].update(length)
    sig["valve"] = {"driver": "sim", "channel": "m1.valve", "raw_min": 0.0, "raw_max": 6.0}
    return sig


def test_home_is_refused_on_an_absolute_sensor(safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(30.0)  # the simulated encoder is absolute by default
    rig.run(0.05)
    v = rig.h.cmd("home", muscle="m1", length_mm=rig.plant.length_mm)
    assert not v["ok"] and "m1.length (driver 'sim') is an absolute sensor" in v["error"]
    assert rig.m.datums.length_offset_mm == 0.0 and not rig.h.ctrl.calibration_dirty


def test_absolute_true_on_an_analog_length_input_references_it_and_refuses_home(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # a potentiometer on an analog input: the driver cannot know it is absolute
    rig = safety_rig(30.0, drivers=_incremental(30.0), muscles=[
        {"name": "m1", "load_kg": 30.0, "signals": _signals(absolute=True)}])
    rig.run(0.05)
    assert rig.m.has_length_datum and rig.m.length_absolute
    v = rig.h.cmd("home", muscle="m1", length_mm=204.0)
    assert not v["ok"] and "absolute sensor" in v["error"]


@pytest.mark.parametrize("load_kg, initial_bar", [(30.0, 0.0), (80.0, 3.0)])
def test_home_is_refused_when_it_disagrees_with_the_expected_length(
        safety_rig: Callable[..., SafetyRig], load_kg: float, initial_bar: float) -> None:
    rig = safety_rig(load_kg, drivers=_incremental(load_kg, initial_bar))
    rig.run(0.3)
    true_mm = rig.plant.length_mm
    # the case: a length nobody measured (a typo, the wrong muscle)
    for wrong in (150.0, true_mm + 8.0, true_mm - 8.0):
        v = rig.h.cmd("home", muscle="m1", length_mm=wrong)
        assert not v["ok"] and "disagrees with the" in v["error"], v
        assert "safety.home_tolerance" in v["error"]
    assert not rig.m.has_length_datum and rig.m.datums.length_offset_mm == 0.0
    ok = rig.h.cmd("home", muscle="m1", length_mm=round(true_mm, 1))
    assert ok["ok"], ok
    rig.run(0.1)
    assert rig.m.has_length_datum and rig.m.length_mm == pytest.approx(true_mm, abs=0.1)
    assert rig.h.state == "IDLE"


def test_home_is_refused_while_the_muscle_moves(safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(30.0, drivers=_incremental(30.0))
    rig.run(0.05)
    rig.cmd("home", muscle="m1", length_mm=rig.plant.length_mm)  # at rest: fine
    rig.cmd("setpoint", muscle="m1", bar=2.0)
    rig.run(0.3)
    rig.cmd("hold")  # HOLD freezes the setpoint; the muscle is still on its way
    v = rig.h.cmd("home", muscle="m1", length_mm=rig.plant.length_mm)
    assert not v["ok"] and "moving at" in v["error"]


def test_tare_refuses_to_call_a_hanging_load_zero(safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(30.0)
    rig.run(0.2)
    before = rig.m.datums.force_offset_n
    v = rig.h.cmd("tare", muscle="m1")
    assert not v["ok"] and "holds the configured load of 30 kg" in v["error"]
    assert "--load-kg 30" in v["error"]
    v = rig.h.cmd("tare", muscle="m1", load_kg=50.0)
    assert not v["ok"] and "configured load is 30 kg" in v["error"]
    assert rig.m.datums.force_offset_n == before
    ok = rig.h.cmd("tare", muscle="m1", load_kg=30.0)
    assert ok["ok"] and abs(ok["force_offset_n"]["m1"]) < 5.0
    rig.run(0.01)
    assert rig.m.force_n == pytest.approx(30.0 * GRAVITY_M_S2, abs=5.0)


def test_tare_refuses_an_undeclared_load(safety_rig: Callable[..., SafetyRig]) -> None:
    # 30 kg really hang, but the config says nothing hangs (and no dead weight: the
    # start-up's load check, which would fault first, does not apply)
    rig = safety_rig(0.0, dead_weight=False, drivers=[{"name": "sim", "type": "sim",
                     "options": {"seed": 1, "muscles": [{"name": "m1", "load_kg": 30.0}]}}])
    rig.run(0.2)
    v = rig.h.cmd("tare", muscle="m1")
    assert not v["ok"] and "would move its offset by +294 N" in v["error"]
    assert "nobody declared" in v["error"]


# -- offline: pamd home / pamd tare -----------------------------------------------------

def _config(tmp_path: Path, load_kg: float) -> Path:
    """config/sim.yaml with an incremental length encoder, virtual clock."""
    data = yaml.safe_load((Path(__file__).resolve().parents[2] / "config" / "sim.yaml")
                          .read_text())
    data["loop"]["clock"] = "virtual"
    data["loop"]["realtime"] = {"enabled": False}
    data["telemetry"] = {"enabled": False}
    data["drivers"] = _incremental(load_kg)
    data["muscles"][0]["load_kg"] = load_kg
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_pamd_home_offline_references_and_saves(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    path = _config(tmp_path, 30.0)
    true_mm = 200.0 * (1.0 - equilibrium_contraction(force_model("map"), 0.0, 30.0, -0.5, 0.9))
    state = tmp_path / "state"  # a simulation keeps its datums where it is told
    cal = state / "calibration.yaml"
    assert main(["home", "--config", str(path), "--muscle", "m1", "--length-mm", "150",
                 "--state-dir", str(state)]) == 4
    assert "disagrees with the" in capsys.readouterr().err
    assert not cal.exists()  # refused: nothing saved
    assert main(["home", "--config", str(path), "--muscle", "m1", "--length-mm",
                 f"{true_mm:.2f}", "--json", "--state-dir", str(state)]) == 0
    out = capsys.readouterr().out
    assert '"ok": true' in out
    datums = load_calibration(str(cal)).muscles["m1"]
    assert datums.has_length_datum and datums.homed_at
    assert "has_length_datum: true" in cal.read_text()  # the new key, written
    assert datums.length_offset_mm == pytest.approx(true_mm, abs=0.1)  # the encoder read 0


def test_pamd_tare_offline_needs_the_load_declared(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    path = _config(tmp_path, 30.0)
    state = tmp_path / "state"
    cal = state / "calibration.yaml"
    assert main(["tare", "--config", str(path), "--muscle", "m1", "--state-dir",
                 str(state)]) == 4
    assert "holds the configured load of 30 kg" in capsys.readouterr().err
    assert not cal.exists()
    assert main(["tare", "--config", str(path), "--muscle", "m1", "--load-kg", "30",
                 "--state-dir", str(state)]) == 0
    ref = load_calibration(str(cal)).muscles["m1"]
    assert ref.tared_at and abs(ref.force_offset_n) < 5.0


def test_a_calibration_file_with_the_old_key_loads(tmp_path: Path) -> None:
    """calibration.yaml's `length_referenced` (before `has_length_datum`, deprecated) is
    read as the new key; pamd writes the new one; both at once is an error naming them."""
    from pamd.loop.devices.datum_file import save_calibration
    from pamd.wire.errors import ConfigError

    old = tmp_path / "calibration.yaml"
    old.write_text("muscles:\n  m1:\n    length_offset_mm: 12.5\n    length_referenced: true\n"
                   "    homed_at: '2026-01-02T03:04:05+0000'\n  m2:\n"
                   "    length_referenced: false\n")
    cal = load_calibration(str(old))
    assert cal.muscles["m1"].has_length_datum and cal.muscles["m1"].length_offset_mm == 12.5
    assert cal.muscles["m1"].homed_at == "2026-01-02T03:04:05+0000"
    assert not cal.muscles["m2"].has_length_datum
    new = tmp_path / "new.yaml"
    save_calibration(cal, str(new))
    assert "has_length_datum: true" in new.read_text() and "referenced" not in new.read_text()
    assert load_calibration(str(new)) == cal
    old.write_text("muscles:\n  m1:\n    has_length_datum: true\n    length_referenced: false\n")
    with pytest.raises(ConfigError, match=r"calibration.yaml:4.*muscles\.m1\.length_referenced"):
        load_calibration(str(old))

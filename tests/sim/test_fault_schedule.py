"""The sim driver's scripted faults (`faults:` in its options) and its incremental
length encoder: each fault kind does what it says, at its time; a schedule naming
what does not exist is refused with the reason, by the driver and by the config;
and a rig's reaction to a fault is shown from the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from pamd.drivers.sim import SimDriver

from pamd.config import load_config
from pamd.sim.faults import SimFault
from pamd.sim.options import SimMuscleOptions, SimOptions
from pamd.wire.errors import ConfigError, DriverError

REPO = Path(__file__).resolve().parents[2]


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def stepped(*faults: SimFault, **muscle: object) -> tuple[SimDriver, Clock]:
    drv = SimDriver("sim", SimOptions(seed=3, faults=faults,
                                      muscles=(SimMuscleOptions(**muscle),)))  # type: ignore[arg-type]
    clock = Clock()
    drv.open(clock)
    return drv, clock


def run(drv: SimDriver, clock: Clock, seconds: float, dt: float = 0.001) -> None:
    for _ in range(round(seconds / dt)):
        clock.t += dt
        drv.advance(dt)


def test_a_scheduled_fault_strikes_at_its_time_on_the_loops_clock() -> None:
    drv, clock = stepped(SimFault(at_s=0.5, muscle="m1", signal="length", failure="dead"))
    run(drv, clock, 0.499)
    assert drv.in_values[2] > 150.0
    run(drv, clock, 0.001)
    assert drv.in_values[2] == 0.0


@pytest.mark.parametrize("signal, index", [("pressure", 0), ("force", 1), ("length", 2)])
def test_jump_and_noisy_sensors(signal: str, index: int) -> None:
    drv, clock = stepped(SimFault(at_s=0.1, muscle="m1", signal=signal, failure="jump", size=7.0))
    clean, cclock = stepped()
    run(drv, clock, 0.2)
    run(clean, cclock, 0.2)
    assert drv.in_values[index] - clean.in_values[index] == pytest.approx(7.0, abs=1e-9)
    noisy, nclock = stepped(SimFault(at_s=0.0, muscle="m1", signal=signal, failure="noisy",
                                     size=2.0))
    clean, cclock = stepped()
    diffs = []
    for _ in range(400):
        run(noisy, nclock, 0.001)
        run(clean, cclock, 0.001)
        diffs.append(noisy.in_values[index] - clean.in_values[index])
    sd = (sum(d * d for d in diffs) / len(diffs)) ** 0.5
    assert sd == pytest.approx(2.0, rel=0.2)


def test_a_stuck_valve_ignores_new_setpoints_and_a_lost_supply_cannot_rise() -> None:
    drv, clock = stepped(SimFault(at_s=0.3, muscle="m1", signal="valve", failure="stuck"))
    drv.write(0, 2.0)
    run(drv, clock, 0.5)
    drv.write(0, 4.0)
    run(drv, clock, 0.5)
    assert drv.plant("m1").pressure_bar == pytest.approx(2.0, abs=0.05)
    drv.clear_faults()
    drv.write(0, 4.0)
    run(drv, clock, 0.5)
    assert drv.plant("m1").pressure_bar == pytest.approx(4.0, abs=0.05)
    drv, clock = stepped(SimFault(at_s=0.0, muscle="m1", signal="supply", failure="lost"))
    drv.write(0, 3.0)
    run(drv, clock, 0.5)
    assert drv.plant("m1").pressure_bar < 0.05


def test_a_driver_error_on_schedule() -> None:
    drv, clock = stepped(SimFault(at_s=0.2, signal="driver", failure="error"))
    run(drv, clock, 0.3)
    assert drv.fault is not None and "injected driver error" in drv.fault


@pytest.mark.parametrize("fault, said", [
    (SimFault(muscle="m9", signal="length", failure="dead"), "no muscle 'm9' in this sim driver"),
    (SimFault(muscle="*", signal="force", failure="dead"), "no muscle '*'"),
    (SimFault(muscle="m1", signal="supply", failure="dead"), "a supply fault is one of lost"),
    (SimFault(muscle="m1", signal="valve", failure="noisy"), "a valve fault is one of stuck"),
    (SimFault(muscle="m1", signal="force", failure="noisy", size=-1.0), "size must be"),
    (SimFault(muscle="m1", signal="length", failure="jump", size=0.0), "a jump of size 0"),
    (SimFault(muscle="m1", signal="length", failure="dead", size=5.0), "size applies to noisy"),
])
def test_a_schedule_naming_what_does_not_exist_is_refused(fault: SimFault, said: str) -> None:
    with pytest.raises(DriverError, match=said.replace("(", r"\(")):
        SimDriver("sim", SimOptions(faults=(fault,)))


def _config(tmp_path: Path, faults: list[dict[str, object]], **muscle: object) -> Path:
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["loop"]["realtime"] = {"enabled": False}
    data["telemetry"] = {"enabled": False}
    data["drivers"][0]["options"]["faults"] = faults
    data["drivers"][0]["options"]["muscles"][0].update(muscle)
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_the_config_refuses_a_bad_schedule_with_file_line_and_reason(tmp_path: Path) -> None:
    path = _config(tmp_path, [{"at_s": 1.0, "muscle": "m2", "signal": "length",
                               "kind": "dead"}])
    with pytest.raises(ConfigError) as err:
        load_config(str(path))
    text = str(err.value)
    assert "rig.yaml:" in text and "drivers[0].options" in text
    assert "no muscle 'm2' in this sim driver (muscles: m1)" in text
    path = _config(tmp_path, [{"at_s": 1.0, "muscle": "m1", "signal": "temperature",
                               "kind": "dead"}])
    with pytest.raises(ConfigError, match="signal"):
        load_config(str(path))


def test_an_incremental_encoder_reads_zero_at_power_up_and_needs_home() -> None:
    drv, clock = stepped(length_absolute=False)
    assert drv.in_values[2] == 0.0 and not drv.is_absolute(2)
    assert drv.is_absolute(0) and drv.is_absolute(1)
    drv.write(0, 3.0)
    run(drv, clock, 1.0)
    assert drv.in_values[2] < -5.0  # shorter than at power-up: contracted


def test_pamd_run_shows_the_rigs_reaction_to_a_scripted_fault(tmp_path: Path) -> None:
    path = _config(tmp_path, [{"at_s": 2.0, "muscle": "m1", "signal": "length",
                               "kind": "dead"}], load_kg=30.0)
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config", str(path), "--clock",
                        "virtual", "--duration", "4", "--profile", "sine", "--min-bar", "1",
                        "--max-bar", "3", "--freq-hz", "0.5", "--json", "--no-record"],
                       capture_output=True, text=True, timeout=120, cwd=REPO)
    assert r.returncode == 1, r.stderr  # a run that ends in FAULT says so in its exit code
    s = json.loads(r.stdout)
    assert s["final_state"] == "FAULT"
    assert s["faults"] and "m1.length reads 0.00 mm" in s["faults"][0]
    assert "FAULT" in r.stderr and "m1.length" in r.stderr

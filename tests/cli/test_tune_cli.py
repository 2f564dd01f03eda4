"""`pamd tune` end to end on the simulated rig (virtual clock: deterministic): the
identified gains agree with bench/tune_pressure_loop.py's (the shipped ones), --save
rewrites the config keeping its comments, and runs outside the limits are refused."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.config import load_config

REPO = Path(__file__).resolve().parents[2]


def tune(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", "tune", "--clock", "virtual", *args],
                          capture_output=True, text=True, timeout=300, cwd=cwd)


@pytest.fixture()
def rig(tmp_path: Path) -> Path:
    path = tmp_path / "sim.yaml"
    path.write_text((REPO / "config" / "sim.yaml").read_text())
    return path


def test_pressure_loop_identified_and_saved_keeping_comments(rig: Path, tmp_path: Path) -> None:
    shipped = yaml.safe_load(rig.read_text())["control"]  # bench/tune_pressure_loop.py's
    before = rig.read_text()
    r = tune("--config", str(rig), "--out", str(tmp_path / "run"), "--save", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "control.pid.kp" in r.stdout and "measured" in r.stdout
    assert "--- " in r.stdout and "+  pid: {kp: " in r.stdout  # the diff was shown
    assert "tune-pressure-m1: 9/9 steps finished (done)" in r.stderr  # progress
    # recorded like any collection: one file per plan step
    names = " ".join(p.name for p in (tmp_path / "run" / "m1").glob("*.mcap"))
    for i, step in enumerate(("level-1_5", "up-1_5", "down-1_5", "level-3", "up-3", "down-3",
                              "level-4_5", "up-4_5", "down-4_5")):
        assert f"_{i + 1:02d}-{step}-bar.mcap" in names
    after = rig.read_text()
    comments = [ln for ln in before.splitlines() if ln.lstrip().startswith("#")]
    assert comments == [ln for ln in after.splitlines() if ln.lstrip().startswith("#")]
    old, new = before.splitlines(), after.splitlines()
    assert [a.split(":")[0] for a in old if a not in new] == ["  pid", "  rate_feedforward_s"]
    assert [b.split(":")[0] for b in new if b not in old] == [
        "  pid", "  rate_feedforward_s", "  plant", "    gain_bar_per_bar", "    lag_s",
        "    dead_time_s"]
    # the plant the gains came from, added to the section: what later gains are judged on
    pid = load_config(str(rig)).rig.control
    assert pid.plant is not None and (pid.plant.gain_bar_per_bar, pid.plant.lag_s,
                                      pid.plant.dead_time_s) == pytest.approx(
        (0.949, 0.0123, 0.0129), rel=0.01)
    # within 3 % of the bench procedure's figures (the step times are read from the
    # recording here, from the command there: 0.1 ms of dead time apart)
    assert pid.pid.kp == pytest.approx(shipped["pid"]["kp"], rel=0.03)
    assert pid.pid.ki_per_s == pytest.approx(shipped["pid"]["ki_per_s"], rel=0.03)
    assert pid.rate_feedforward_s == pytest.approx(shipped["rate_feedforward_s"], rel=0.03)
    # the figures docs/how-to/tune.md reports
    assert (pid.pid.kp, pid.pid.ki_per_s, pid.rate_feedforward_s) == pytest.approx(
        (0.501, 40.8, 0.0252), rel=0.01)


def test_position_loop_agrees_with_the_bench_and_writes_nothing(rig: Path,
                                                                  tmp_path: Path) -> None:
    before = rig.read_text()
    png = tmp_path / "tune.png"
    r = tune("--config", str(rig), "--loop", "position", "--out", str(tmp_path / "run"),
             "--plot", str(png), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert rig.read_text() == before and "nothing written" in r.stdout
    shipped = yaml.safe_load(before)["control"]["position"]["pid"]
    rows = {ln.split()[0]: ln.split() for ln in r.stdout.splitlines()
            if ln.strip().startswith("control.position.pid.")}
    kp = float(rows["control.position.pid.kp_bar_per_mm"][2])
    ki = float(rows["control.position.pid.ki_bar_per_mm_s"][2])
    assert kp == pytest.approx(shipped["kp_bar_per_mm"], rel=0.02)  # 0.0661 vs 0.0656
    assert ki == pytest.approx(shipped["ki_bar_per_mm_s"], rel=0.02)  # 2.10 vs 2.08
    assert "Model: gain -6.596" in r.stdout  # docs/how-to/tune.md's figure (-6.60 mm/bar)


@pytest.mark.parametrize(("args", "reason"), [
    (("--step-bar", "0.8"), "step of 0.8 bar is not allowed"),
    (("--loop", "position", "--step-bar", "1.5"), "step of 1.5 bar is not allowed"),
    (("--levels", "5.9"), "leaves the pressure limit"),
    (("--levels", "1.0"), "below the safe pressure 1.58 bar with 80 kg"),
    (("--muscle", "m9"), "no muscle 'm9'"),
])
def test_runs_outside_the_limits_are_refused(rig: Path, tmp_path: Path, args: tuple[str, ...],
                                             reason: str, pamd_here: Any) -> None:
    rig.write_text(rig.read_text().replace("load_kg: 30", "load_kg: 80"))
    before = rig.read_text()
    r = pamd_here("tune", "--clock", "virtual", "--config", str(rig), "--out",
                  str(tmp_path / "run"), "--save", *args, cwd=tmp_path)
    assert r.returncode == 2 and reason in r.stderr, r.stderr
    assert rig.read_text() == before
    assert not list(tmp_path.rglob("*.mcap"))  # nothing ran


def test_a_run_without_a_response_is_refused(rig: Path, tmp_path: Path) -> None:
    """The regulator sticks once the first level is reached (a scripted fault of the
    simulated rig): the steps get no response, so no model; the present gains are
    kept and the reason printed."""
    rig.write_text(rig.read_text().replace(
        "      seed: 1\n", "      seed: 1\n      faults: [{at_s: 1.0, muscle: m1, signal: valve, "
        "kind: stuck}]\n"))
    before = rig.read_text()
    r = tune("--config", str(rig), "--out", str(tmp_path / "run"), "--save",
             "--levels", "1.5", cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "pressure loop not identified" in r.stderr and "use a larger step" in r.stderr
    assert "present gains are kept" in r.stderr
    assert rig.read_text() == before


def test_a_fault_during_the_run_stops_it(rig: Path, tmp_path: Path) -> None:
    """The pressure sensor goes silent mid-run: the rig goes to its safe state, tune
    says why, keeps the present gains and the recording."""
    rig.write_text(rig.read_text().replace(
        "      seed: 1\n", "      seed: 1\n      faults: [{at_s: 3.0, muscle: m1, signal: "
        "pressure, kind: silent}]\n"))
    before = rig.read_text()
    r = tune("--config", str(rig), "--out", str(tmp_path / "run"), "--save", cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "the tuning run stopped" in r.stderr and "present gains are kept" in r.stderr
    assert "m1.pressure from driver 'sim' is stale" in r.stderr.split("run stopped")[1]
    assert rig.read_text() == before
    assert list((tmp_path / "run" / "m1").glob("*.mcap"))


def test_save_needs_a_config_file(tmp_path: Path, pamd_here: Any) -> None:
    r = pamd_here("tune", "--save", cwd=tmp_path)
    assert r.returncode == 2 and "name it with --config" in r.stderr
    assert not list(tmp_path.rglob("*.mcap"))


def test_help_teaches(pamd_here: Any) -> None:
    r = pamd_here("tune", "--help")
    assert r.returncode == 0
    for words in ("What it does to the rig", "How long", "What it writes", "--save"):
        assert words in r.stdout


def rig_copy(tmp_path: Path, name: str) -> Path:
    """config/<name>.yaml copied into `tmp_path`, or for "mixed" `mixed_rig`."""
    if name == "mixed":
        return mixed_rig(tmp_path)
    path = tmp_path / f"{name}.yaml"
    path.write_text((REPO / "config" / f"{name}.yaml").read_text())
    return path


def mixed_rig(tmp_path: Path) -> Path:
    """config/sim-onoff.yaml's on/off muscle m1 beside config/sim.yaml's regulator
    muscle as m2 (with sim.yaml's control section)."""
    d = yaml.safe_load((REPO / "config" / "sim-onoff.yaml").read_text())
    s = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    d["drivers"][0]["options"]["muscles"].append(
        {**s["drivers"][0]["options"]["muscles"][0], "name": "m2"})
    m2 = {**s["muscles"][0], "name": "m2"}
    m2["signals"] = {k: {**v, "channel": v["channel"].replace("m1", "m2")}
                     for k, v in m2["signals"].items()}
    d["muscles"].append(m2)
    d["control"] = s["control"]
    path = tmp_path / "mixed.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


@pytest.mark.parametrize(("config", "args"), [
    ("sim-onoff", ()), ("sim-onoff", ("--loop", "position")), ("mixed", ()),
    ("mixed", ("--method", "relay")), ("mixed", ("--muscle", "m1"))])
def test_on_off_valves_are_refused_before_anything_moves(tmp_path: Path, pamd_here: Any,
                                                          config: str,
                                                          args: tuple[str, ...]) -> None:
    """The pressure and position loops are a regulator's: on an on/off muscle the run
    is refused at once, saying what tunes on/off valves, not after the whole plan with
    a fit that failed."""
    rig = rig_copy(tmp_path, config)
    before = rig.read_text()
    r = pamd_here("tune", "--clock", "virtual", "--config", str(rig), "--out",
                  str(tmp_path / "run"), "--save", *args, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "m1 is on on/off valves (actuation: onoff)" in r.stderr
    assert "tune them with pamd tune --loop onoff" in r.stderr
    assert "Nothing was moved" in r.stderr
    assert ("--muscle m2" in r.stderr) == (config == "mixed")  # the way on, if any
    assert rig.read_text() == before
    assert not (tmp_path / "run").exists()  # nothing ran, nothing recorded


def test_regulator_muscles_of_a_mixed_rig_go_on(tmp_path: Path, pamd_here: Any) -> None:
    """--muscle naming only the regulator muscle passes the on/off check: the next
    check (the level's limit) is what refuses it, still before anything moves."""
    rig = mixed_rig(tmp_path)
    r = pamd_here("tune", "--clock", "virtual", "--config", str(rig), "--out",
                  str(tmp_path / "run"), "--muscle", "m2", "--levels", "5.9", cwd=tmp_path)
    assert r.returncode == 2
    assert "on/off" not in r.stderr and "m2: level 5.9 bar + step 0.2 bar leaves" in r.stderr

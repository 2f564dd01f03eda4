"""Training pairs from recordings (pamd.models.data.recordings, .extraction, .splitting): CSV
and MCAP, what is dropped, the velocity filter shared with the tick, the split, and bad
data refused."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pamd.models.data.extraction import extract, load_samples
from pamd.models.data.recordings import read_csv, read_runs
from pamd.models.data.samples import ExtractOptions
from pamd.models.data.splitting import split
from pamd.models.velocity import VELOCITY_WINDOW_S, filtered_velocity, velocity_step
from pamd.wire.errors import ModelError
from pamd.wire.tick import Flag, State

REPO = Path(__file__).resolve().parents[3]


def write_csv(path: Path, n: int = 3000, rate_hz: float = 100.0, **cols: np.ndarray) -> Path:
    """A lab-style CSV: time, force, length, pressure of a slow sweep (+ extra columns)."""
    t = np.arange(n) / rate_hz
    p = 3.0 + 2.5 * np.sin(2 * np.pi * 0.05 * t)
    length = 200.0 - 6.0 * p + 0.3 * np.cos(2 * np.pi * 0.05 * t)
    force = 294.0 + 2.0 * np.sin(2 * np.pi * 0.5 * t)
    data = {"t_s": t, "force_n": force, "length_mm": length, "pressure_bar": p, **cols}
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(data))
        for i in range(n):
            w.writerow([repr(float(data[k][i])) for k in data])
    return path


def test_csv_pairs_drop_settling_and_flags_and_decimate(tmp_path: Path) -> None:
    flags = np.zeros(3000)
    flags[1000:1100] = int(Flag.SOFT_LIMIT_CONTRACTION)  # 1 s of soft limit
    flags[2000:2010] = int(Flag.SLEW_LIMITED)  # kept: the measurement is sound
    path = write_csv(tmp_path / "lab.csv", flags=flags)
    s = load_samples([str(path)], ExtractOptions(settle_s=2.0, rate_hz=10.0))
    assert s.inputs == ("force_n", "length_mm") and s.output == "pressure_bar"
    assert s.t_s.min() >= 2.0  # the first 2 s settle
    assert not np.any((s.t_s >= 10.0) & (s.t_s < 11.0))  # the soft-limit second
    assert np.any((s.t_s >= 20.0) & (s.t_s < 20.1))  # slew-limited samples stay
    assert np.all(np.diff(s.t_s) >= 0.1 - 1e-9)  # decimated to 10 Hz
    dropped = s.runs[0]["dropped"]
    assert dropped["settling"] == 200 and dropped["flag SOFT_LIMIT_CONTRACTION"] == 100


def test_exhaust_open_drops_the_sample_except_on_onoff_valves(tmp_path: Path) -> None:
    """A regulator's open exhaust is the exhaust valve venting past it: dropped. On on/off
    valves (the recording's config says so) both valves open within PWM periods as the
    control itself: kept, as the inflate valve's pulses always were."""
    flags = np.zeros(3000)
    flags[1000:1100] = int(Flag.EXHAUST_OPEN)
    flags[1500:1600] = int(Flag.INFLATE_OPEN)
    run = read_csv(str(write_csv(tmp_path / "valves.csv", flags=flags)))
    opts = ExtractOptions(settle_s=2.0, rate_hz=100.0)
    regulator = extract([run], opts)
    assert regulator.runs[0]["dropped"]["flag EXHAUST_OPEN"] == 100
    assert not np.any((regulator.t_s >= 10.0) & (regulator.t_s < 11.0))
    assert np.any((regulator.t_s >= 15.0) & (regulator.t_s < 16.0))
    run.meta["actuation"] = "onoff"
    onoff = extract([run], opts)
    assert "flag EXHAUST_OPEN" not in onoff.runs[0]["dropped"]
    assert np.count_nonzero((onoff.t_s >= 10.0) & (onoff.t_s < 11.0)) >= 90
    assert len(onoff) > len(regulator)


def test_a_table_without_config_takes_the_actuation_option(tmp_path: Path) -> None:
    """A lab's own table carries no config: read as a regulator's unless the option says
    on/off; a file whose config says its actuation keeps it (the file knows its rig).
    Each run's provenance says which was used, the model's extraction the option."""
    flags = np.zeros(3000)
    flags[1000:1100] = int(Flag.EXHAUST_OPEN)
    run = read_csv(str(write_csv(tmp_path / "lab.csv", flags=flags)))
    plain = extract([run], ExtractOptions(settle_s=2.0, rate_hz=100.0))
    assert plain.runs[0]["actuation"] is None
    assert plain.runs[0]["dropped"]["flag EXHAUST_OPEN"] == 100
    onoff = extract([run], ExtractOptions(settle_s=2.0, rate_hz=100.0, actuation="onoff"))
    assert onoff.runs[0]["actuation"] == "onoff"
    assert "flag EXHAUST_OPEN" not in onoff.runs[0]["dropped"]
    assert len(onoff) >= len(plain) + 95  # (a few fall to the decimation's bins)
    assert onoff.provenance()["extraction"]["actuation"] == "onoff"
    run.meta["actuation"] = "proportional"  # as pamd's own recordings of a regulator say
    said = extract([run], ExtractOptions(settle_s=2.0, rate_hz=100.0, actuation="onoff"))
    assert said.runs[0]["actuation"] == "proportional"
    assert said.runs[0]["dropped"]["flag EXHAUST_OPEN"] == 100
    with pytest.raises(ModelError, match="unknown actuation 'pwm'; use one of proportional"):
        extract([run], ExtractOptions(actuation="pwm"))


def test_an_onoff_recording_says_its_actuation(tmp_path: Path, recording: Path) -> None:
    """The actuation comes from the recording's own config: a PWM sweep on on/off
    valves keeps its exhaust pulses; the regulator's recording is read as one."""
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config", "config/sim-onoff.yaml",
                        "--clock", "virtual", "--profile", "sine", "--freq-hz", "0.2",
                        "--min-bar", "1", "--max-bar", "4", "--cycles", "1", "--record",
                        str(tmp_path), "--no-telemetry"],
                       capture_output=True, text=True, timeout=120, cwd=REPO)
    assert r.returncode == 0, r.stderr
    (path,) = tmp_path.glob("*.mcap")
    (run,) = read_runs([str(path)])
    assert run.meta["actuation"] == "onoff"
    flags = run.columns["flags"].astype(np.int64)
    assert np.count_nonzero(flags & int(Flag.EXHAUST_OPEN)) > 100  # the PWM's pulses
    s = extract([run], ExtractOptions(settle_s=1.0))
    assert "flag EXHAUST_OPEN" not in s.runs[0]["dropped"]
    assert [r.meta["actuation"] for r in read_runs([str(recording)])] == ["proportional"]
    # `pamd export --csv`'s tables say it through their sidecar's copy of the config
    from pamd.client.export import export_named_csv
    from pamd.client.training_tables import load_samples as load_tables

    out = export_named_csv(str(path), str(tmp_path / "csv"))
    table = out["m1"][0]
    from_csv = load_tables([table], ExtractOptions(settle_s=1.0), report=lambda _l: None)
    assert "flag EXHAUST_OPEN" not in from_csv.runs[0]["dropped"]
    assert abs(len(from_csv) - len(s)) <= 0.02 * len(s)
    pytest.importorskip("scipy.io")  # `pamd export --mat`'s file says it too
    from pamd.client.export import export_mat

    mat = str(tmp_path / "sweep.mat")
    export_mat(str(path), mat)
    from_mat = load_tables([mat], ExtractOptions(settle_s=1.0), report=lambda _l: None)
    assert "flag EXHAUST_OPEN" not in from_mat.runs[0]["dropped"]


def test_csv_semicolons_and_case_and_log_time(tmp_path: Path) -> None:
    path = tmp_path / "matlab.csv"
    t = np.arange(500) * 0.01
    with open(path, "w") as fh:
        fh.write("log_time_ns;Force_N;Length_mm;Pressure_bar;note\n")
        for i, ti in enumerate(t):
            fh.write(f"{int(ti * 1e9) + 10**18};{290 + i % 7};{180 + 0.01 * i};"
                     f"{1 + 0.004 * i};x\n")
    s = load_samples([str(path)], ExtractOptions(settle_s=0.5))
    assert len(s) == 225 and s.t_s[0] == pytest.approx(0.5)


def test_velocity_is_the_ticks_filter(tmp_path: Path) -> None:
    """Velocity pairs come from length at full rate through velocity_step, then decimation."""
    path = write_csv(tmp_path / "v.csv", n=2000, rate_hz=1000.0)
    run = read_csv(str(path))
    window = 0.2
    s = extract([run], ExtractOptions(inputs=("force_n", "length_mm", "velocity_mm_s"),
                                      settle_s=0.0, rate_hz=100.0, velocity_window_s=window))
    v, prev, t_prev = 0.0, math.nan, math.nan
    by_t = {}
    for t, x in zip(run.t_s, run.columns["length_mm"], strict=True):
        v = velocity_step(v, prev, x, t - t_prev, window)
        prev, t_prev = x, t
        by_t[round(float(t), 6)] = v
    expected = [by_t[round(float(t), 6)] for t in s.t_s]
    assert s.X[:, 2] == pytest.approx(expected, abs=1e-12)
    assert filtered_velocity(run.t_s, run.columns["length_mm"], window)[-1] == v


@pytest.mark.parametrize("kind, message", [
    ("nan", "column 'force_n' has 1 NaN"),
    ("missing", "missing column(s) pressure_bar"),
    ("constant", "input 'force_n' is constant"),
    ("few", "too few samples"),
    ("notime", "no time column"),
    ("backwards", "time does not increase"),
])
def test_bad_csv_is_refused_naming_the_problem(tmp_path: Path, kind: str, message: str) -> None:
    path = tmp_path / f"{kind}.csv"
    if kind == "missing":
        write_csv(path)
        text = path.read_text().splitlines()
        path.write_text("\n".join(",".join(r.split(",")[:3]) for r in text))
    elif kind == "few":
        write_csv(path, n=250)  # 2 s settle leaves 0.5 s = 25 samples at 50 Hz
    elif kind == "notime":
        write_csv(path)
        path.write_text(path.read_text().replace("t_s,", "clock,", 1))
    else:
        write_csv(path)
        rows = path.read_text().splitlines()
        cells = [r.split(",") for r in rows]
        if kind == "nan":
            cells[1500][1] = "nan"
        elif kind == "constant":
            for r in cells[1:]:
                r[1] = "294.0"
        elif kind == "backwards":
            cells[100][0] = "0.5"
        path.write_text("\n".join(",".join(r) for r in cells))
    with pytest.raises(ModelError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_samples([str(path)])


def test_split_keeps_blocks_and_runs_apart(tmp_path: Path) -> None:
    a = write_csv(tmp_path / "a.csv", n=6000)
    b = write_csv(tmp_path / "b.csv", n=6000)
    s = load_samples([str(a), str(b)], ExtractOptions(settle_s=0.0))
    parts = split(s, 0.25, 0.25, by="block", block_s=5.0, seed=3)
    assert parts.validation is not None and parts.test is not None
    def blocks(x):
        return {(int(r), int(t // 5.0)) for r, t in zip(x.run, x.t_s, strict=True)}
    tr, va, te = blocks(parts.train), blocks(parts.validation), blocks(parts.test)
    assert not (tr & va) and not (tr & te) and not (va & te)
    assert len(parts.train) + len(parts.validation) + len(parts.test) == len(s)
    same = split(s, 0.25, 0.25, by="block", block_s=5.0, seed=3)
    assert np.array_equal(same.test.t_s, parts.test.t_s)  # reproducible for a seed
    by_run = split(s, 0.5, 0.0, by="run", seed=0)
    assert set(by_run.train.run).isdisjoint(set(by_run.validation.run))
    with pytest.raises(ModelError, match="too few"):
        split(s, 0.5, 0.4, by="run")  # 2 runs: one each for validation and test


def test_mcap_pairs_keep_only_the_running_sweep(recording: Path) -> None:
    runs = read_runs([str(recording)])
    assert len(runs) == 1 and runs[0].muscle == "m1" and runs[0].load_kg == 30.0
    run = runs[0]
    s = extract(runs, ExtractOptions(settle_s=1.0, rate_hz=50.0))
    dropped = s.runs[0]["dropped"]
    # The profile starts at 0 bar: its lead-in ramp to mid-range (2.75 bar at 1 bar/s)
    # plus the settling second are dropped; so are the idle ticks around the sweep.
    assert dropped["lead-in ramp"] >= 2700
    assert dropped["not running (idle, hold, load change, fault, estop)"] > 100
    assert s.t_s.min() >= 2.75 + 1.0 - 0.01
    running = run.columns["state"] == int(State.RUNNING)
    assert s.t_s.max() <= run.t_s[running].max()
    # The measured pressure really is the output (bar) at those times.
    i = np.searchsorted(run.t_s, s.t_s)
    assert s.y == pytest.approx(run.columns["pressure_bar"][i])


def test_mcap_velocity_equals_the_recorded_tick_velocity(recording: Path) -> None:
    """With the tick's window, the extracted velocity is the velocity the tick recorded:
    one filter for training and the tick."""
    runs = read_runs([str(recording)])
    s = extract(runs, ExtractOptions(inputs=("force_n", "length_mm", "velocity_mm_s"),
                                     velocity_window_s=VELOCITY_WINDOW_S, settle_s=0.0))
    run = runs[0]
    i = np.searchsorted(run.t_s, s.t_s)
    assert s.X[:, 2] == pytest.approx(run.columns["velocity_mm_s"][i], abs=1e-9)


def test_unknown_inputs_and_muscles_are_refused(recording: Path) -> None:
    with pytest.raises(ModelError, match="unknown input"):
        load_samples([str(recording)], ExtractOptions(inputs=("force_n", "stiffness")))
    with pytest.raises(ModelError, match="no muscle 'm9'"):
        read_runs([str(recording)], muscle="m9")
    with pytest.raises(ModelError, match="no such file"):
        read_runs([str(recording) + ".missing"])


def test_pamd_export_csv_gives_the_same_pairs(recording: Path, tmp_path: Path) -> None:
    """The CSVs of `pamd export` (state taken from the loop file beside the muscle's)
    give the pairs the MCAP file gives, but for the lead-in, which only MCAP events
    tell (so its settling is dropped by --settle-s alone)."""
    from pamd.wire.record.files import export_csv

    out = export_csv(str(recording), str(tmp_path / "csv"))
    muscle_csv = next(p for t, (p, _n) in out.items() if t.endswith("/state/m1"))
    opts = ExtractOptions(settle_s=1.0)
    from_csv = load_samples([muscle_csv], opts)
    from_mcap = load_samples([str(recording)], opts)
    assert "not running (idle, hold, load change, fault, estop)" in from_csv.runs[0]["dropped"]
    assert from_csv.runs[0]["muscle"] == "m1"
    both = np.intersect1d(np.round(from_csv.t_s, 6), np.round(from_mcap.t_s, 6))
    # Every MCAP pair is a CSV pair too, but maybe the first (the CSV keeps the lead-in,
    # so the first 20 ms bin after it can pick a different tick).
    assert both.size >= len(from_mcap) - 1

"""What a lab's scripts, configs, recordings and model files rely on keeps working
(issue 41 item 3): the names below are pamd's promise, and CHANGELOG.md says when one
changes. Moving a module inside pamd never breaks them: the old module names are the
new modules (`pamd._moved`), told where the code is now.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
import subprocess
import sys
import warnings
from importlib.metadata import entry_points
from pathlib import Path

import pytest
import tomllib
from pamd.drivers import Driver

import pamd
from pamd import _moved

ROOT = Path(__file__).resolve().parents[1]

#: the drivers pamd installs under the `pamd.drivers` entry point group
DRIVERS = {"sim", "modbus", "serial-line", "canopen-encoder", "nidaqmx"}
#: the Python API (`pamd.__all__`)
API = {"CommandRefused", "Event", "MuscleData", "NoDaemon", "PamdError", "Recording",
       "RecordingError", "RecordingIncomplete", "RigClient", "StateBatch", "__version__",
       "connect", "open_recording"}
#: `pamd <verb>`
CLI_VERBS = ["run", "check-config", "collect", "tune", "commission", "inspect", "export",
             "recover", "emulate", "train", "evaluate", "safe-outputs", "install-service",
             "home", "tare", "status", "cmd", "token", "watch", "router", "model", "plot"]
#: what a client may send (`pamd cmd <verb>`, `RigClient.command`)
COMMAND_VERBS = ["setpoint", "profile", "mode", "model", "adapt", "hold", "resume", "stop",
                 "estop", "reset", "home", "tare", "load", "confirm", "pause", "collect"]
#: the config's sections
CONFIG_SECTIONS = ["rig_id", "loop", "drivers", "muscles", "control", "safety",
                   "safety_chain", "recording", "telemetry", "calibration_file", "state_dir"]
#: the recorded fields (MCAP topics, `open_recording`'s arrays, the exports' columns)
LOOP_FIELDS = ("tick", "t_s", "wake_latency_s", "compute_s", "overruns", "state",
               "lost_records", "segment", "safety_chain", "supply_bar", "heartbeat")
MUSCLE_FIELDS = ("pressure_bar", "force_n", "length_mm", "contraction", "velocity_mm_s",
                 "setpoint_bar", "feedforward_bar", "pid_p_bar", "pid_i_bar", "pid_d_bar",
                 "valve_cmd_bar", "target_length_mm", "target_force_n", "safe_pressure_bar",
                 "mode", "flags", "adapt_drift_bar", "adapt_state")
#: the columns the exports add
DERIVED_COLUMNS = ("load_kg", "file")
#: the tick flags' names and bits (`flags`): a deprecated name keeps its bit, beside its
#: new one, until it goes (`pamd.wire.declare.deprecated`)
FLAG_BITS = {"STALE": 1, "SOFT_LIMIT_PRESSURE": 2, "SOFT_LIMIT_CONTRACTION": 4,
             "PRETENSION_LIMIT": 8, "SLEW_LIMITED": 16, "OUTPUT_SATURATED": 32,
             "FF_CLIPPED": 64, "NO_LENGTH_DATUM": 128, "EXHAUST_OPEN": 256, "TRACKING": 512,
             "INFLATE_OPEN": 1024, "FF_OFF_DATA": 2048, "FF_FADED": 4096,
             "FF_OSCILLATING": 8192, "NOT_REFERENCED": 128}


def test_the_drivers_entry_points_and_the_driver_contract() -> None:
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "entry-points"]["pamd.drivers"]
    assert set(declared) == DRIVERS
    found = {e.name: e for e in entry_points(group="pamd.drivers")}
    assert set(found) >= DRIVERS, "pamd is not installed with its entry points"
    for name in DRIVERS:
        assert issubclass(found[name].load(), Driver), name


def test_the_python_api() -> None:
    assert set(pamd.__all__) == API
    for name in API:
        assert getattr(pamd, name) is not None, name
    assert callable(pamd.open_recording) and callable(pamd.connect)
    from pamd.models.anfis import TrainingOptions, fit

    assert callable(fit) and TrainingOptions().__class__.__name__ == "TrainingOptions"


def test_the_cli_verbs_the_commands_and_the_config_sections() -> None:
    from pamd.client.cli.main import COMMANDS
    from pamd.config.schema import RigConfig
    from pamd.wire.verbs.table import VERBS

    assert [c.name for c in COMMANDS] == CLI_VERBS
    assert [v.name for v in VERBS if not v.internal] == COMMAND_VERBS
    assert [f.name for f in dataclasses.fields(RigConfig)] == CONFIG_SECTIONS


def test_the_recorded_field_names_and_the_export_columns() -> None:
    from pamd.client.export import matlab_name
    from pamd.wire.declare import fields

    assert fields.LOOP_NAMES == LOOP_FIELDS
    assert fields.MUSCLE_NAMES == MUSCLE_FIELDS
    assert tuple(f.name for f in fields.DERIVED) == DERIVED_COLUMNS
    # the MATLAB export names a field as recorded: no column renamed on the way out
    assert all(matlab_name(n) == n for n in (*LOOP_FIELDS, *MUSCLE_FIELDS, *DERIVED_COLUMNS))


def test_the_flag_names_and_bits() -> None:
    """Every flag's name keeps its bit (recordings hold bits), in `Flag` and in the
    exports' flag tables; an old name resolves to its new one's bit."""
    from pamd.client.field_info import FLAG_BITS as exported
    from pamd.wire.tick import Flag

    assert {n: int(f) for n, f in Flag.__members__.items()} == FLAG_BITS
    assert exported == FLAG_BITS


def test_the_shipped_configs_and_an_old_model_file_load() -> None:
    from pamd.config import load_config
    from pamd.models.registry import load_model

    for path in sorted((ROOT / "config").glob("*.yaml")):
        assert load_config(str(path)).rig.rig_id, path
    model = load_model(ROOT / "tests" / "models" / "fixtures" / "anfis-v1.json")
    assert model.kind == "anfis"


def test_an_old_module_name_is_the_new_module_and_says_so() -> None:
    from pamd.client import recording

    with pytest.warns(FutureWarning, match="pamd.view.recording is now pamd.client.recording"):
        old = importlib.import_module("pamd.view.recording")
    assert old is recording and old.open_recording is pamd.open_recording
    with pytest.warns(FutureWarning, match="pamd.control is now pamd.loop.control"):
        from pamd.control import pid
    assert pid is importlib.import_module("pamd.loop.control.pid")


def test_python_m_of_an_old_module_name_runs_the_new_one() -> None:
    """docs/how-to/foxglove.md said `python -m pamd.view.layout` before the move."""
    done = subprocess.run([sys.executable, "-m", "pamd.view.layout", "--help"],
                          capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "--config" in done.stdout and "pamd.client.layout" in done.stderr


#: an import statement's module (`import X`, `from X import`), at a line's start
IMPORT = re.compile(r"^\s*(?:from|import)\s+(pamd[\w.]*)", re.M)


def test_nothing_of_pamd_imports_an_old_name() -> None:
    """The old names are for users' scripts: pamd's own code, tests and benches import
    the modules where they are (a stale name would only warn, so this finds it)."""
    old = set(_moved.MOVED) | set(_moved.REMOVED)
    wrong = []
    for base in ("pamd", "drivers", "tests", "bench"):
        for path in sorted((ROOT / base).rglob("*.py")):
            if path.name == "_moved.py" or path == Path(__file__).resolve():
                continue
            text = path.read_text()
            wrong += [f"{path.relative_to(ROOT)}: {m.group(1)}" for m in IMPORT.finditer(text)
                      if m.group(1) in old]
    assert not wrong, "\n".join(wrong)


def test_the_io_process_never_loads_the_old_names() -> None:
    """Only an import nothing else finds reaches the finder: a present name does not."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        importlib.import_module("pamd.wire.verbs.table")
    code = ("import sys, pamd.iohost.process; "
            "print('pamd._moved' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, timeout=60)
    assert done.stdout.strip() == "False", done.stderr

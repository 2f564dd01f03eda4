"""State that survives a restart, kept in the state directory as small JSON files
written atomically (temp file, fsync, rename, fsync of the directory):

* the latched fault (`fault.json`): its state (FAULT or ESTOP), reason and time. A
  daemon started again comes back latched until someone sends `reset`;
* the last known-good safe outputs (`safe-outputs.json`): per driver its type and
  options, and per output channel the raw value of the present safe state. The
  second-line command `pamd safe-outputs` replays them when the daemon is gone and
  the config may be unreadable;
* the home/tare datums (`calibration.yaml`) unless the config names its own
  `calibration_file`.

The state directory is, the first that applies: `--state-dir DIR` (the service:
/var/lib/pamd); the config's `state_dir` (relative to the config file); for a
real-clock run of a config, `$XDG_STATE_HOME/pamd/<rig_id>` (by default
~/.local/state/pamd/<rig_id>): never beside the config. A private simulation keeps
no state unless a directory is named: a virtual-clock run, and the built-in
simulated rig (no `--config`). A run that keeps state locks its state directory
(pamd.daemon.service.riglock): two daemons never write one fault file.

Everything here is file I/O: it runs in the daemon's main thread, never in the
loop's.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pamd.config.loader import LoadedConfig, builtin_config_path
from pamd.drivers.safe_outputs import safe_output_values
from pamd.wire.atomic import fsync_dir, write_atomic
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import PamdError

if TYPE_CHECKING:  # a type only: reading the state files needs no controller
    from pamd.daemon.service.ports import KeptRig

FAULT_FORMAT = "pamd-fault"
SAFE_OUTPUTS_FORMAT = "pamd-safe-outputs"
FORMAT_VERSION = 1
FAULT_FILE = "fault.json"
SAFE_OUTPUTS_FILE = "safe-outputs.json"
CALIBRATION_FILE = "calibration.yaml"
EARLIER_KEPT = 10


class StateFileError(PamdError):
    """A state file exists but cannot be read or understood."""

    exit_code = 2


@dataclass(frozen=True)
class StatePaths:
    """Where one daemon keeps its persistent state."""

    directory: str
    fault: str
    safe_outputs: str
    calibration: str

    @classmethod
    def in_dir(cls, directory: str) -> StatePaths:
        d = os.path.abspath(os.path.expanduser(directory))
        return cls(d, os.path.join(d, FAULT_FILE), os.path.join(d, SAFE_OUTPUTS_FILE),
                   os.path.join(d, CALIBRATION_FILE))

    @property
    def claim(self) -> str:
        """The state directory as a resource a run locks (pamd.daemon.service.riglock)."""
        return f"state directory {self.directory}"


def state_home() -> str:
    """Where real-clock runs keep their state by default: `$XDG_STATE_HOME/pamd`, else
    ~/.local/state/pamd."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(
        os.path.expanduser("~"), ".local", "state")
    return os.path.join(base, "pamd")


def state_paths(cfg: LoadedConfig, state_dir: str | None = None) -> StatePaths | None:
    """The state paths of `cfg` (`state_dir` overrides the config's `state_dir`);
    None for a private simulation (virtual clock, or the built-in simulated rig)
    without an explicit directory."""
    if state_dir:
        return StatePaths.in_dir(state_dir)
    config_dir = os.path.dirname(os.path.abspath(cfg.path))
    if cfg.rig.state_dir:
        return StatePaths.in_dir(os.path.join(config_dir, os.path.expanduser(cfg.rig.state_dir)))
    if cfg.rig.loop.clock == "virtual":
        return None  # a simulation as fast as possible: private, deterministic
    if os.path.abspath(cfg.path) == os.path.abspath(builtin_config_path()):
        return None
    return StatePaths.in_dir(os.path.join(state_home(), cfg.rig.rig_id))


def calibration_path(cfg: LoadedConfig, paths: StatePaths | None) -> str | None:
    """Where the home/tare datums are kept: the config's `calibration_file`, else
    the state directory's calibration.yaml; None: for this run only (no state)."""
    if cfg.calibration_path:
        return cfg.calibration_path
    return paths.calibration if paths is not None else None


def now_iso() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


# -- atomic JSON ----------------------------------------------------------------------
#: the state files are the daemon's own (as mkstemp made them before)
STATE_FILE_MODE = 0o600


def write_json_atomic(path: str, doc: JsonObject) -> None:
    """Write `doc` so that a crash or power cut leaves the old file or the new one,
    never half of one (`pamd.wire.atomic`: FileWriteError, an OSError, if it cannot)."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    write_atomic(path, json.dumps(doc, indent=2, allow_nan=False) + "\n",
                 file_mode=STATE_FILE_MODE)


def remove_durably(path: str) -> bool:
    """Remove `path` (and make the removal durable); False if it was not there."""
    try:
        os.unlink(path)
    except FileNotFoundError:
        return False
    fsync_dir(os.path.dirname(os.path.abspath(path)))
    return True


def read_json(path: str, fmt: str) -> JsonObject | None:
    """The document in `path` (None if there is no file); StateFileError if it is
    unreadable, not JSON, or not a `fmt` document of a known version."""
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise StateFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise StateFileError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        raise StateFileError(f"{path}: not a {fmt} file")
    if doc.get("version") != FORMAT_VERSION:
        raise StateFileError(f"{path}: {fmt} version {doc.get('version')!r}; this pamd "
                             f"reads version {FORMAT_VERSION}")
    return doc


# -- the latched fault -------------------------------------------------------------------
@dataclass(frozen=True)
class FaultRecord:
    """A latched fault as persisted."""

    state: str  # FAULT or ESTOP
    reason: str
    since: str  # ISO time it latched
    earlier: tuple[str, ...] = ()  # reasons latched before it and never reset

    def restored_reason(self) -> str:
        """The reason a restarted daemon latches with: the original, and that it
        was kept across a restart."""
        what = "emergency stop" if self.state == "ESTOP" else "fault"
        return f"{self.reason} [{what} latched {self.since}, kept across a restart]"


def read_fault(path: str) -> FaultRecord | None:
    doc = read_json(path, FAULT_FORMAT)
    if doc is None:
        return None
    state, reason = doc.get("state"), doc.get("reason")
    if state not in ("FAULT", "ESTOP") or not isinstance(reason, str):
        raise StateFileError(f"{path}: needs state FAULT or ESTOP and a reason")
    earlier = doc.get("earlier") or []
    return FaultRecord(state, reason, str(doc.get("since", "?")),
                       tuple(str(e) for e in earlier if isinstance(e, str)))


def write_fault(path: str, record: FaultRecord, cfg: LoadedConfig) -> None:
    write_json_atomic(path, {
        "format": FAULT_FORMAT, "version": FORMAT_VERSION,
        "state": record.state, "reason": record.reason, "since": record.since,
        "earlier": list(record.earlier[-EARLIER_KEPT:]),
        "rig_id": cfg.rig.rig_id, "config": os.path.abspath(cfg.path), "pid": os.getpid(),
        "how_to_clear": "send reset to the running daemon once the cause is gone",
    })


# -- the safe outputs ---------------------------------------------------------------------
def options_as_json(options: object) -> JsonValue:
    """A driver's validated options as plain JSON values (the driver's schema
    builds them back)."""
    if dataclasses.is_dataclass(options) and not isinstance(options, type):
        return _plain(dataclasses.asdict(options))
    return _plain(options)


def _plain(value: object) -> JsonValue:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def safe_outputs_document(cfg: LoadedConfig, ctrl: KeptRig) -> JsonObject:
    """What `pamd safe-outputs` needs to put the rig in its present safe state with
    no config: per driver its type and options, per output its channel and raw
    value (the same values `push_safe_outputs` gives the devices)."""

    labels: dict[tuple[str, int], tuple[str, float, str]] = {}
    for m in ctrl.muscles:
        for b, value, unit in m.actuation.safe_outputs(m.safe_pressure_bar):
            labels[(b.driver.name, b.index)] = (b.name, value, unit)
    by_name = {d.name: d for d in cfg.rig.drivers}
    drivers = []
    for drv, values in safe_output_values(ctrl).items():
        dcfg = by_name[drv.name]
        outputs = []
        for index in sorted(values):
            signal, si, unit = labels.get((drv.name, index), ("", float("nan"), ""))
            outputs.append({"channel": drv.output_channels[index].name, "raw": values[index],
                            "signal": signal, "si": si, "si_unit": unit})
        drivers.append({"name": drv.name, "type": dcfg.type,
                        "options": options_as_json(dcfg.options), "outputs": outputs})
    return {
        "format": SAFE_OUTPUTS_FORMAT, "version": FORMAT_VERSION,
        "rig_id": cfg.rig.rig_id, "config": os.path.abspath(cfg.path),
        "config_sha256": cfg.sha256,
        "loads_kg": {m.name: m.load_kg for m in ctrl.muscles},
        "drivers": drivers,
    }


def write_safe_outputs(path: str, doc: JsonObject) -> None:
    write_json_atomic(path, dict(doc, saved_at=now_iso()))


def read_safe_outputs(path: str) -> JsonObject | None:
    doc = read_json(path, SAFE_OUTPUTS_FORMAT)
    if doc is None:
        return None
    drivers = doc.get("drivers")
    if not isinstance(drivers, list) or not all(
            isinstance(d, dict) and isinstance(d.get("name"), str)
            and isinstance(d.get("type"), str) and isinstance(d.get("outputs"), list)
            for d in drivers):
        raise StateFileError(f"{path}: 'drivers' must be a list of drivers with name, type "
                             "and outputs")
    return doc

"""The status snapshot, built here, in one place, by the daemon's main thread a few
times a second (never by the loop's thread, never per tick); its fields are declared
in `pamd.wire.status`. The io process answers it from the board."""

from __future__ import annotations

import getpass
import os
import time
from collections.abc import Callable
from typing import Protocol, cast

from pamd.config.loader import LoadedConfig
from pamd.daemon.host.parts import RecordingState
from pamd.loop.control.controller import RigController
from pamd.loop.control.muscle import MuscleController
from pamd.loop.control.rig_report import muscle_status
from pamd.loop.experiment.sequencer import running_plan
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.status import (
    ExperimentStatus,
    MuscleStatus,
    RecordingStatus,
    Status,
    jsonsafe,
    with_old_keys,
)
from pamd.wire.verbs.table import VERBS
from pamd.wire.version import __version__


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return f"uid {os.getuid()}"


def recording_status(io: RecordingState | None) -> RecordingStatus | None:
    """What the status says of the recording (None: nothing records)."""
    if io is None or not io.recording:
        return None
    return {"files": io.files(), "failure": io.failure, "lost_records": io.lost_records}


class StatusLoop(Protocol):
    """What the status says of the loop (`pamd.loop.loop.Loop`)."""

    virtual: bool
    clock_name: str  # real, virtual or daq

    @property
    def stop_requested(self) -> str | None: ...


class StatusBuilder:
    """Builds the status (`pamd.wire.status.Status`, every field declared there) in the
    daemon's main thread, in this one place. It gets what it reads, not the daemon:
    the rig's controller, the loop, the config in force (`config`), the recording's
    state (`recording`: None when nothing records) and the remote collection that
    runs, if any (`collection`)."""

    def __init__(self, ctrl: RigController, loop: StatusLoop,
                 config: Callable[[], LoadedConfig],
                 recording: Callable[[], RecordingStatus | None] = lambda: None,
                 collection: Callable[[], JsonObject | None] = lambda: None) -> None:
        self.ctrl = ctrl
        self.loop = loop
        self.config = config
        self.recording = recording
        self.collection = collection
        self.t0 = time.monotonic()
        self.user = _user()  # whose daemon it is (a status says so)

    def build(self, now: float) -> Status:
        ctrl, cfg, sup, chain = self.ctrl, self.config(), self.ctrl.supervisor, self.ctrl.chain
        seq = running_plan(ctrl)
        experiment: ExperimentStatus | None = None
        if seq is not None:
            experiment = {"plan": seq.plan.name, "step": seq.index, "phase": seq.phase,
                          "outcome": seq.outcome or None,
                          "awaiting_operator": seq.awaiting_operator or None,
                          "collection": self.collection()}
        st: Status = {
            "rig_id": cfg.rig.rig_id, "state": sup.state.name, "reason": sup.reason,
            "fault": sup.fault_reason, "faults": list(sup.faults), "reload": ctrl.reload_note,
            "safety_chain": None if not chain.configured else {
                "closed": None if chain.closed != chain.closed else bool(chain.closed),
                "supply_bar": None if chain.supply_bar != chain.supply_bar
                else chain.supply_bar,
                "supply_out": chain.supply_out, "reset_by": chain.reset_by},
            "muscles": {m.name: self._muscle(m) for m in ctrl.muscles},
            "experiment": experiment, "config_sha256": cfg.sha256,
            "config_path": os.path.abspath(cfg.path),
            "clock": self.loop.clock_name,
            "rate_hz": cfg.rig.loop.rate_hz, "verbs": sorted(VERBS.names),
            "recording": self.recording(), "stopping": self.loop.stop_requested,
            "pamd_version": __version__, "pid": os.getpid(), "user": self.user,
            "t_wall_s": time.time(), "uptime_s": now - self.t0,
        }
        return cast(Status, jsonsafe(st))

    def _muscle(self, m: MuscleController) -> MuscleStatus:
        """The muscle's status as the rig controller says it (`muscle_status`, built
        there once), and what only the daemon's status adds: the datums, the model, its
        adaptation and feedforward, the deadman; and, for this release, the deprecated
        old keys (`pamd.wire.status.with_old_keys`)."""
        d = m.datums
        ff = m.length_control.ff
        dm = self.ctrl.deadman.get(m.name)
        return cast(MuscleStatus, with_old_keys({
            **muscle_status(m),
            "datums": {
                "has_length_datum": d.has_length_datum, "homed_at": d.homed_at,
                "tared_at": d.tared_at, "length_offset_mm": d.length_offset_mm,
                "force_offset_n": d.force_offset_n},
            "model": ff.describe() if ff is not None else None,
            "adapt": m.adaptation.describe(),  # online adaptation (pamd.loop.control.adapt)
            "feedforward": m.feedforward_report(),  # off its data (pamd.loop.control.off_data)
            "deadman_left_s": None if dm is None else max(0.0, dm[0] - self.ctrl.now),
        }))

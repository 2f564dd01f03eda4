"""What survives a restart (one job of the service keeper, `pamd.daemon.service.keeper`):
the latched fault is written to the state directory when the supervisor latches it
and removed when it is reset, and a daemon started again comes back latched
(`restore()`, before start); a loop the main thread sees stalled past the stall fault
limit is persisted as a fault at once, so a daemon the watchdog had to kill comes back
latched; the present safe outputs are saved whenever they change, for
`pamd safe-outputs`. A state file that cannot be written is logged once, never fatal.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from pamd.config.loader import LoadedConfig
from pamd.daemon.service.ports import KeptLoop, KeptRig, tick_gap_s
from pamd.daemon.service.state import (
    FaultRecord,
    StateFileError,
    StatePaths,
    now_iso,
    read_fault,
    remove_durably,
    safe_outputs_document,
    write_fault,
    write_safe_outputs,
)
from pamd.wire.tick import State

log = logging.getLogger("pamd")


class StateKeeper:
    """The state directory's files of one daemon (`paths` None: nothing persisted)."""

    def __init__(self, rig: KeptRig, loop: KeptLoop, config: Callable[[], LoadedConfig],
                 paths: StatePaths | None, journal: bool) -> None:
        """`journal`: the daemon runs under systemd (saving the safe outputs is then
        said at INFO, else at DEBUG)."""
        self.rig = rig
        self.supervisor = rig.supervisor
        self.loop = loop
        self.config = config
        self.paths = paths
        self.journal = journal
        self.persisted: tuple[str, str] | None = None  # (state, reason) the fault file holds
        self.earlier: list[str] = []  # reasons persisted before, never reset
        self._plain = ""  # the reason as the fault file holds it
        self.restored: FaultRecord | None = None
        self._stall_persisted = False
        self._seen_latched = False  # the supervisor latched since the file was written
        self._safe_key: tuple[object, ...] | None = None
        self._io_errors: set[str] = set()

    def restore(self) -> FaultRecord | None:
        """Before start: a fault latched before a restart latches again (the
        controller re-latches `fault_reason` once the sensors are read)."""
        if self.paths is None:
            return None
        path = self.paths.fault
        try:
            rec = read_fault(path)
        except StateFileError as exc:
            rec = FaultRecord("FAULT", f"the fault state file is unreadable ({exc}); latched "
                              "to be safe", now_iso())
        if rec is None:
            return None
        text = rec.restored_reason()
        self.supervisor.restore_fault_reason(text, estop=rec.state == "ESTOP")
        self.restored = rec
        self.persisted = (rec.state, text)
        self.earlier, self._plain = list(rec.earlier), rec.reason
        log.error("latched %s restored from %s: %s; the rig holds its measured pressure "
                  "until reset", "emergency stop" if rec.state == "ESTOP" else "fault",
                  path, rec.reason)
        return rec

    def service(self) -> None:
        """Every 50 ms (and at close): each file up to date."""
        self._persist_fault()
        self._persist_stall()
        self.save_safe_outputs()

    def _io(self, what: str, fn: Callable[..., object], *args: object) -> bool:
        """Run one state-file operation; a failure is logged once, never fatal."""
        try:
            fn(*args)
        except OSError as exc:
            msg = f"cannot {what}: {exc}"
            if msg not in self._io_errors:
                self._io_errors.add(msg)
                log.error("%s (the state does NOT survive a restart until this is fixed)", msg)
            return False
        return True

    def _persist_fault(self) -> None:
        if self.paths is None:
            return
        sup = self.supervisor
        state, reason = sup.state, sup.fault_reason
        if state in (State.FAULT, State.ESTOP):
            if reason is None:  # a reset half done in the loop's thread: next time
                return
            self._seen_latched = True
            want = (state.name, reason)
            if want != self.persisted and self._write_fault(state.name, reason, want):
                log.info("latched %s saved in %s", state.name, self.paths.fault)
        elif (self._seen_latched and state != State.STARTING and reason is None
              and self.persisted is not None
              and self._io("remove the latched fault", remove_durably, self.paths.fault)):
            # a reset: the supervisor latched (or re-latched what was restored), and
            # now it is not. A stall saved by the main thread waits for the loop's own
            # stall fault, which comes with the first tick after the stall.
            self.persisted = None
            self.earlier = []
            self.restored = None
            self._stall_persisted = False
            self._seen_latched = False
            log.info("fault reset: %s removed", self.paths.fault)

    def _persist_stall(self) -> None:
        """A loop seen stalled is saved as a latched fault now: if it never ticks
        again, systemd kills pamd and the restarted daemon comes back latched."""
        loop = self.loop
        if self.paths is None or loop.virtual or not loop.running or self._stall_persisted:
            return
        gap = tick_gap_s(loop)
        if not gap > loop.stall_fault_s or self.supervisor.latched:
            return
        reason = (f"loop stalled: no tick completed for at least {1000 * gap:.0f} ms (limit "
                  f"{1000 * loop.stall_fault_s:.0f} ms), seen by the main thread")
        if self._write_fault("FAULT", reason, ("FAULT", reason)):
            self._stall_persisted = True
            log.error("%s; saved as a latched fault in %s", reason, self.paths.fault)

    def _write_fault(self, state: str, reason: str, key: tuple[str, str]) -> bool:
        """Persist a latched fault; the one it replaces (never reset) goes to `earlier`."""
        assert self.paths is not None
        earlier = [*self.earlier, self._plain] if self.persisted is not None else self.earlier
        rec = FaultRecord(state, reason, now_iso(), tuple(earlier))
        if not self._io("save the latched fault", write_fault, self.paths.fault, rec,
                        self.config()):
            return False
        self.earlier, self.persisted, self._plain = list(earlier), key, reason
        return True

    def save_safe_outputs(self) -> None:
        """The present safe outputs, saved if they changed since last saved."""
        if self.paths is None:
            return
        ctrl = self.rig
        cfg = self.config()
        key = (cfg.sha256, *((m.safe_pressure_bar, m.load_kg) for m in ctrl.muscles))
        if key == self._safe_key:
            return
        doc = safe_outputs_document(cfg, ctrl)
        if self._io("save the safe outputs", write_safe_outputs, self.paths.safe_outputs, doc):
            self._safe_key = key
            loads = ", ".join(f"{m.name} {m.safe_pressure_bar:.2f} bar" for m in ctrl.muscles)
            # the service's journal says it; a run in a terminal (and `pamd tune`, whose
            # refusal would follow "saved") says it with -v only
            log.log(logging.INFO if self.journal else logging.DEBUG,
                    "safe outputs saved in %s (%s)", self.paths.safe_outputs, loads)

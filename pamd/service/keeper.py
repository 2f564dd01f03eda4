"""The service keeper: what a daemon does in its main thread so that it can live
under systemd for months. `Daemon.service()` calls `ServiceKeeper.service()` every
50 ms (from `wait()`); nothing here runs in the loop's thread.

* notify: `READY=1` once the loop ticks (even with a device missing: the rig is
  then in FAULT and STATUS says why), `WATCHDOG=1` every half watchdog period while
  the loop ticks on time (a stalled loop gets no pings and systemd restarts it; a
  FAULT is not a stall), `STATUS=` with the supervisor's state and reason,
  `STOPPING=1` on shutdown, `RELOADING=1` ... `READY=1` around a reload;
* persistence: the latched fault is written to the state directory when the
  supervisor latches it and removed when it is reset; a daemon started again comes
  back latched (`restore()`, before start). The present safe outputs are saved
  whenever they change, for `pamd safe-outputs`;
* a loop the main thread sees stalled past the stall fault limit (`pamd.stalls`:
  `loop.stall_fault_s` or what the actuation holds by itself) is persisted as a
  fault at once, so a daemon the watchdog had to kill comes back latched;
* SIGHUP: the config is read again, validated and applied through the loop's
  mailbox (`pamd.service.reload`); changes that reopen the devices wait for IDLE
  and then restart the daemon in place (`pamd.service.restart`), where `pamd run`
  allows it (`restart_in_place`).

Outside systemd the notifier is disabled and only the persistence remains.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from pamd.commands import Command
from pamd.commands.model_file import check_models_isolated
from pamd.commands.pending import PendingCommand
from pamd.config.loader import LoadedConfig, load_config
from pamd.errors import PamdError
from pamd.rt import RealtimeSession
from pamd.safety.supervisor import Supervisor
from pamd.service.notify import Notifier
from pamd.service.reload import ReloadPlan, describe, plan_reload
from pamd.service.state import (
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
from pamd.tick import State
from pamd.timing import TickTiming

log = logging.getLogger("pamd")

RT_SCAN_S = 1.0  # how often threads started meanwhile are raised below the loop


class KeptRig(Protocol):
    """What the keeper uses of the rig's controller (`pamd.controller.RigController`):
    its supervisor (the latched fault, the state), the reload's fate, the muscles' safe
    pressures (the safe outputs kept)."""

    @property
    def supervisor(self) -> Supervisor: ...
    @property
    def reload_note(self) -> dict[str, Any] | None: ...
    @property
    def muscles(self) -> Sequence[SafeMuscleView]: ...
    def at_rest(self) -> bool: ...


class SafeMuscleView(Protocol):
    @property
    def name(self) -> str: ...
    @property
    def safe_pressure_bar(self) -> float: ...
    @property
    def load_kg(self) -> float: ...


class KeptLoop(Protocol):
    """What the keeper uses of the loop (`pamd.loop.Loop`): whether it ticks and when it
    last did (systemd's watchdog, the stall the main thread sees), how it ended, the
    real-time session of its process, and the reload's hand-over and stall limits."""

    running: bool
    virtual: bool
    handed_over: bool
    stopped_reason: str
    last_tick_done: float
    stall_s: float
    timing: TickTiming
    rt: RealtimeSession
    notices: deque[str]

    @property
    def stall_fault_s(self) -> float: ...
    def request_handover(self, reason: str) -> None: ...
    def set_stall_limits(self, cfg: LoadedConfig) -> None: ...


class ServiceKeeper:
    """Main-thread housekeeping of one daemon: notify, persistence, reload. It gets the
    parts it looks after, not the daemon: the rig's controller and the loop (read
    through `KeptRig`, `KeptLoop`), `submit` (a command into the loop's mailbox) and the
    config in force (`config`, and `apply_config` once a reload is in force)."""

    def __init__(self, rig: KeptRig, loop: KeptLoop, submit: Callable[[Command], None],
                 config: Callable[[], LoadedConfig], apply_config: Callable[[LoadedConfig], None],
                 paths: StatePaths | None, notifier: Notifier | None = None,
                 config_overrides: dict[str, Any] | None = None) -> None:
        self.rig = rig
        self.supervisor = rig.supervisor
        self.loop = loop
        self.submit = submit
        self.config = config
        self.apply_config = apply_config
        self.paths = paths
        self.notifier = notifier if notifier is not None else Notifier(None)
        self.config_overrides = config_overrides
        # notify
        self.ready_sent = False
        self.stopping_sent = False
        self.stop_reason: str | None = None
        self.last_status: str | None = None
        self.pings = 0
        self._next_ping = 0.0
        self._withholding = False
        self._next_rt_scan = 0.0
        # persistence
        self.persisted: tuple[str, str] | None = None  # (state, reason) the fault file holds
        self.earlier: list[str] = []  # reasons persisted before, never reset
        self._plain = ""  # the reason as the fault file holds it
        self.restored: FaultRecord | None = None
        self._stall_persisted = False
        self._seen_latched = False  # the supervisor latched since the file was written
        self._safe_key: tuple[Any, ...] | None = None
        self._io_errors: set[str] = set()
        # reload
        self.reload_requested = False
        self.started_cfg: LoadedConfig = config()
        self.gains_cfg: LoadedConfig = self.started_cfg
        self.limits_cfg: LoadedConfig = self.started_cfg
        self.pending: tuple[ReloadPlan, Any] | None = None
        self.deferred: ReloadPlan | None = None
        # changes that reopen the devices: `pamd run` can restart in place (a
        # library daemon, a virtual run cannot, and such a reload is refused)
        self._restart_in_place = False
        self.handover: str | None = None  # the changes a restart waiting for IDLE applies
        self.handing_over = False  # the loop was asked to end at an IDLE tick

    def allow_restart_in_place(self) -> None:
        """`pamd run` can exec itself again: a reload that reopens the devices restarts
        in place instead of being refused."""
        self._restart_in_place = True

    # -- life cycle (called by the Daemon) -------------------------------------------------
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
        self.supervisor.restore_fault_reason(text)
        self.restored = rec
        self.persisted = ("FAULT", text)
        self.earlier, self._plain = list(rec.earlier), rec.reason
        log.error("latched %s restored from %s: %s; the rig holds its measured pressure "
                  "until reset", "emergency stop" if rec.state == "ESTOP" else "fault",
                  path, rec.reason)
        return rec

    def started(self) -> None:
        """The drivers are open: save the safe outputs before the loop runs."""
        self._save_safe_outputs()

    def stop_requested(self, reason: str) -> None:
        """Daemon.stop() (possibly from a signal handler): only remember it."""
        if self.stop_reason is None:
            self.stop_reason = reason

    def close(self) -> None:
        self._send_stopping()
        self.service_persistence()
        self.notifier.close()

    # -- every 50 ms -----------------------------------------------------------------------
    def service(self) -> None:
        self.service_persistence()
        self._notify()
        self._reload()
        self._raise_new_threads()

    def _raise_new_threads(self) -> None:
        loop = self.loop
        now = time.monotonic()
        if loop.running and now >= self._next_rt_scan:
            self._next_rt_scan = now + RT_SCAN_S
            loop.rt.raise_others(loop.notices.append)

    def service_persistence(self) -> None:
        self._persist_fault()
        self._persist_stall()
        self._save_safe_outputs()

    # -- notify ----------------------------------------------------------------------------
    def status_text(self) -> str:
        sup = self.supervisor
        text = f"{sup.state.name}: {sup.reason}"
        note = self.rig.reload_note
        if self.deferred is not None:
            text += " (config reload waiting for the rig to rest)"
        elif note is not None and note["outcome"] == "refused":
            text += f" (config reload refused: {note['reason']})"
        if self.handover is not None:
            text += " (restart in place for a config reload waiting for IDLE)"
        return text

    def _notify(self) -> None:
        n = self.notifier
        loop = self.loop
        status = self.status_text()
        if not self.ready_sent and loop.running and loop.timing.ticks > 0:
            self.ready_sent = True
            self.last_status = status
            n.ready(status)
            self._next_ping = 0.0
        elif status != self.last_status:
            self.last_status = status
            n.status(status)
        if self.stop_reason is not None or loop.stopped_reason:
            self._send_stopping()
        interval = n.ping_interval_s
        if interval is None or not self.ready_sent:
            return
        now = time.monotonic()
        if now < self._next_ping:
            return
        if self.loop_on_time():
            n.watchdog()
            self.pings += 1
            self._next_ping = now + interval
            if self._withholding:
                self._withholding = False
                log.warning("the loop ticks on time again: watchdog pings resumed")
        elif not self._withholding and loop.running:
            self._withholding = True
            log.error("the loop has not completed a tick for %.0f ms: watchdog pings "
                      "withheld (systemd restarts pamd if this lasts)", 1000 * self.tick_gap_s())

    def tick_gap_s(self) -> float:
        """Seconds since the loop last completed a tick (NaN before the first)."""
        now = time.monotonic()  # read first: a late main thread never sees a false gap
        return now - self.loop.last_tick_done

    def loop_on_time(self) -> bool:
        loop = self.loop
        return loop.running and self.tick_gap_s() < loop.stall_s

    def _send_stopping(self) -> None:
        if self.stopping_sent or self.loop.handed_over:
            return  # a restart in place is a reload, not a stop
        self.stopping_sent = True
        reason = self.stop_reason or self.loop.stopped_reason or "shutting down"
        self.notifier.stopping(f"stopping ({reason}): ramping to the safe state and "
                               "finalising the recording")

    # -- persistence -------------------------------------------------------------------------
    def _io(self, what: str, fn: Any, *args: Any) -> bool:
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
        gap = self.tick_gap_s()
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

    def _save_safe_outputs(self) -> None:
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
            log.log(logging.INFO if self.notifier.enabled else logging.DEBUG,
                    "safe outputs saved in %s (%s)", self.paths.safe_outputs, loads)

    # -- reload (SIGHUP) -----------------------------------------------------------------------
    def _reload(self) -> None:
        if self.pending is not None:
            plan, pending = self.pending
            if not pending.done:
                return  # one reload at a time; a new SIGHUP waits for this verdict
            self.pending = None
            self._reload_verdict(plan, pending.verdict)
        if self.reload_requested:
            self.reload_requested = False
            try:
                self._begin_reload()
            except Exception:  # a reload must never take the running rig down
                log.exception("reload failed; still running on the config loaded before")
                self._finish()
        elif (self.handover is not None and not self.handing_over and self.pending is None
              and self.supervisor.state == State.IDLE):
            self.handing_over = True
            self.notifier.reloading()
            log.warning("the rig is IDLE: the loop ends holding the outputs, then pamd "
                        "restarts in place (%s)", self.handover)
            self.loop.request_handover(f"config reload: {self.handover}")
        elif (self.deferred is not None and self.pending is None
              and self.rig.at_rest()):  # not during a stop's ramp (issue 23)
            plan = self._plan(self.deferred.cfg)
            log.info("the rig is at rest: applying the deferred reload (%s)",
                     ", ".join(plan.idle) or "nothing left")
            self._submit(plan)

    def _plan(self, new: LoadedConfig) -> ReloadPlan:
        return plan_reload(self.started_cfg, self.gains_cfg, self.limits_cfg, new)

    def _finish(self) -> None:
        self.last_status = self.status_text()
        self.notifier.ready(self.last_status)

    def _begin_reload(self) -> None:
        path = self.config().path
        self.notifier.reloading()
        log.info("SIGHUP: reloading %s", path)
        try:
            new = load_config(path, self.config_overrides)
            check_models_isolated(new)  # a model_file that does not fit is refused now
            # (read in a child process: a model's parse would stall the loop running here)
        except PamdError as exc:
            log.error("reload refused, still running on the config loaded before: %s", exc)
            self._finish()
            return
        except Exception as exc:  # noqa: BLE001 - a reload must never take the daemon down
            log.error("reload refused (%s: %s), still running on the config loaded before",
                      type(exc).__name__, exc)
            self._finish()
            return
        plan = self._plan(new)
        if self.handing_over:
            log.warning("reload: pamd is restarting in place already; the restarted daemon "
                        "reads %s again", path)
            return
        if self.handover is not None:
            log.info("reload: the restart in place waiting for IDLE is superseded by this "
                     "reload")
            self.handover = None
        if plan.restart:
            self._restart_when_idle(plan)
            return
        if self.deferred is not None:
            log.info("reload: the deferred reload is superseded by this one")
            self.deferred = None
        if not (plan.now or plan.idle):
            log.info("reload: %s has no changes to apply", path)
            self._finish()
            return
        self._submit(plan)

    def _restart_when_idle(self, plan: ReloadPlan) -> None:
        """Changes that reopen the devices: a restart in place once the rig is IDLE
        (`_reload`), or refused where this daemon cannot restart in place."""
        what = describe(plan.restart, self.started_cfg, plan.cfg)
        if not self._restart_in_place or self.loop.virtual:
            why = ("a virtual-clock run" if self.loop.virtual
                   else "this daemon is not `pamd run`")
            log.error("reload refused, still running on the config loaded before: %s "
                      "changed, which reopens the devices, and %s cannot restart in place: "
                      "needs a restart (systemctl restart pamd)", what, why)
            self._finish()
            return
        self.deferred = None  # the restart applies everything
        self.handover = what
        state = self.supervisor.state
        log.warning("reload: %s changed, which reopens the devices: pamd restarts in place "
                    "%s", what, "now (the rig is IDLE)" if state == State.IDLE else
                    f"once the rig is IDLE (it is {state.name}; `pamd cmd stop` ends what "
                    "runs)")
        if state != State.IDLE:
            self._finish()

    def _submit(self, plan: ReloadPlan) -> None:
        pending = PendingCommand()
        self.submit(Command("reload", plan.args, pending.set, sender="SIGHUP"))
        self.pending = (plan, pending)

    def _reload_verdict(self, plan: ReloadPlan, verdict: dict[str, Any]) -> None:
        if not verdict.get("ok"):
            log.error("reload refused: %s", verdict.get("error"))
            self.deferred = None
            self._finish()
            return
        old_gains, self.gains_cfg = self.gains_cfg, plan.cfg
        self.loop.set_stall_limits(plan.cfg)
        if plan.now:
            log.warning("reload: applied at once: %s", describe(plan.now, old_gains, plan.cfg))
        if verdict.get("deferred"):
            self.deferred = plan
            log.warning("reload: deferred until the rig is at rest (it is %s): %s",
                        verdict.get("state"), ", ".join(verdict["deferred"]))
        else:
            self.deferred = None
            if plan.idle:
                log.warning("reload: applied while IDLE: %s",
                            describe(plan.idle, self.limits_cfg, plan.cfg))
            self.limits_cfg = plan.cfg
            self.apply_config(plan.cfg)  # everything in it is now in force
        self._finish()

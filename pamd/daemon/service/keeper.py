"""The service keeper: what a daemon does in its main thread so that it can live
under systemd for months. `Daemon.service()` calls `ServiceKeeper.service()` every
50 ms (from `wait()`); nothing here runs in the loop's thread. Each job is a part of
its own, and the keeper ties them to one daemon:

* notify (`pamd.daemon.service.watchdog`): `READY=1` once the loop ticks, `WATCHDOG=1`
  while it ticks on time (from a thread of its own: what the main thread does never
  delays a ping), `STATUS=` with the supervisor's state and reason, `STOPPING=1` on
  shutdown, `RELOADING=1` ... `READY=1` around a reload;
* persistence (`pamd.daemon.service.persistence`): the latched fault in the state directory
  (a daemon started again comes back latched, `restore()` before start), a stall the
  main thread sees saved as a fault at once, the safe outputs for `pamd safe-outputs`;
* SIGHUP (`pamd.daemon.service.reloader`): the config read again and validated in a child
  process, then applied through the loop's mailbox; changes that reopen the devices
  restart the daemon in place once the rig is at rest (`pamd.daemon.service.restart`), where
  `pamd run` allows it;
* the real-time scan: threads started meanwhile are raised below the loop.

The keeper gets the parts it looks after through narrow ports
(`pamd.daemon.service.ports`), not the daemon. Outside systemd the notifier is disabled and
only the persistence remains.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from pamd.config.loader import LoadedConfig
from pamd.daemon.service.notify import Notifier
from pamd.daemon.service.persistence import StateKeeper
from pamd.daemon.service.ports import KeptLoop, KeptRig, SafeMuscleView, tick_gap_s
from pamd.daemon.service.reload import ReloadPlan
from pamd.daemon.service.reloader import Reloader
from pamd.daemon.service.state import FaultRecord, StatePaths
from pamd.daemon.service.watchdog import Watchdog
from pamd.loop.commands import Command
from pamd.loop.commands.pending import PendingCommand
from pamd.wire.declare.jsonsafe import JsonObject

__all__ = ["RT_SCAN_S", "KeptLoop", "KeptRig", "SafeMuscleView", "ServiceKeeper"]

RT_SCAN_S = 1.0  # how often threads started meanwhile are raised below the loop


class ServiceKeeper:
    """Main-thread housekeeping of one daemon: notify, persistence, reload. It gets the
    parts it looks after, not the daemon: the rig's controller and the loop (read
    through `KeptRig`, `KeptLoop`), `submit` (a command into the loop's mailbox) and the
    config in force (`config`, and `apply_config` once a reload is in force)."""

    def __init__(self, rig: KeptRig, loop: KeptLoop, submit: Callable[[Command], None],
                 config: Callable[[], LoadedConfig], apply_config: Callable[[LoadedConfig], None],
                 paths: StatePaths | None, notifier: Notifier | None = None,
                 config_overrides: JsonObject | None = None) -> None:
        self.rig = rig
        self.supervisor = rig.supervisor
        self.loop = loop
        self.paths = paths
        self.notifier = notifier if notifier is not None else Notifier(None)
        self.watchdog = Watchdog(loop, self.notifier, self.status_text)
        self.persistence = StateKeeper(rig, loop, config, paths, self.notifier.enabled)
        self.reloader = Reloader(rig, loop, submit, config, apply_config, self.notifier,
                                 self.watchdog.ready_again, config_overrides,
                                 self.watchdog.handing_over)
        self._next_rt_scan = 0.0

    def allow_restart_in_place(self) -> None:
        """`pamd run` can exec itself again: a reload that reopens the devices restarts
        in place instead of being refused."""
        self.reloader.restart_in_place = True

    # -- the reload's state, as the daemon and `pamd run` see it ------------------------------
    @property
    def reload_requested(self) -> bool:
        """A SIGHUP came (set by the daemon's handler; the next `service` reloads)."""
        return self.reloader.requested

    @reload_requested.setter
    def reload_requested(self, requested: bool) -> None:
        self.reloader.requested = requested

    @property
    def pending(self) -> tuple[ReloadPlan, PendingCommand] | None:
        """The reload waiting for the loop's verdict."""
        return self.reloader.pending

    @property
    def deferred(self) -> ReloadPlan | None:
        """The reload waiting for the rig to rest."""
        return self.reloader.deferred

    @property
    def handover(self) -> str | None:
        """The changes a restart in place waiting for rest applies."""
        return self.reloader.handover

    # -- life cycle (called by the Daemon) -------------------------------------------------
    def restore(self) -> FaultRecord | None:
        """Before start: a fault latched before a restart latches again."""
        return self.persistence.restore()

    def started(self) -> None:
        """The drivers are open: save the safe outputs before the loop runs."""
        self.persistence.save_safe_outputs()

    def stop_requested(self, reason: str) -> None:
        """Daemon.stop() (possibly from a signal handler): only remember it."""
        self.watchdog.stop_requested(reason)

    def close(self) -> None:
        self.watchdog.send_stopping()
        self.persistence.service()
        self.reloader.close()
        self.watchdog.close()  # no more pings: the end, or a restart in place's exec
        self.notifier.close()

    # -- every 50 ms -----------------------------------------------------------------------
    def service(self) -> None:
        self.persistence.service()
        self.watchdog.service()
        self.reloader.service()
        self._raise_new_threads()

    def _raise_new_threads(self) -> None:
        loop = self.loop
        now = time.monotonic()
        if loop.running and now >= self._next_rt_scan:
            self._next_rt_scan = now + RT_SCAN_S
            loop.rt.raise_others(loop.notices.append)

    def service_persistence(self) -> None:
        self.persistence.service()

    def status_text(self) -> str:
        """systemd's STATUS line: the supervisor's state and reason, and what a reload
        waits for or why it was refused."""
        sup = self.supervisor
        text = f"{sup.state.name}: {sup.reason}"
        note = self.rig.reload_note
        if self.reloader.deferred is not None:
            text += " (config reload waiting for the rig to rest)"
        elif note is not None and note["outcome"] == "refused":
            text += f" (config reload refused: {note['reason']})"
        if self.reloader.handover is not None:
            text += " (restart in place for a config reload waiting for the rig to rest)"
        return text

    def tick_gap_s(self) -> float:
        """Seconds since the loop last completed a tick (NaN before the first)."""
        return tick_gap_s(self.loop)

    def loop_on_time(self) -> bool:
        return self.watchdog.loop_on_time()

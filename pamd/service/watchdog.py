"""What systemd is told (one job of the service keeper, `pamd.service.keeper`):
`READY=1` once the loop ticks (even with a device missing: the rig is then in FAULT
and STATUS says why), `WATCHDOG=1` every half watchdog period while the loop ticks on
time (a stalled loop gets no pings and systemd restarts it; a FAULT is not a stall),
`STATUS=` with the supervisor's state and reason, `STOPPING=1` on shutdown.
Outside systemd the notifier is disabled and this sends nothing."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

from pamd.service.notify import Notifier
from pamd.service.ports import KeptLoop, tick_gap_s

log = logging.getLogger("pamd")


class Watchdog:
    """systemd's notifications of one daemon; `status_text` gives the STATUS line."""

    def __init__(self, loop: KeptLoop, notifier: Notifier,
                 status_text: Callable[[], str]) -> None:
        self.loop = loop
        self.notifier = notifier
        self.status_text = status_text
        self.ready_sent = False
        self.stopping_sent = False
        self.stop_reason: str | None = None
        self.last_status: str | None = None
        self.pings = 0
        self._next_ping = 0.0
        self._withholding = False

    def stop_requested(self, reason: str) -> None:
        """Daemon.stop() (possibly from a signal handler): only remember it."""
        if self.stop_reason is None:
            self.stop_reason = reason

    def ready_again(self) -> None:
        """A reload is over (applied, deferred or refused): READY=1 with the status."""
        self.last_status = self.status_text()
        self.notifier.ready(self.last_status)

    def service(self) -> None:
        """Every 50 ms: READY once, STATUS when it changes, STOPPING once, the pings."""
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
            self.send_stopping()
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
                      "withheld (systemd restarts pamd if this lasts)",
                      1000 * tick_gap_s(loop))

    def loop_on_time(self) -> bool:
        loop = self.loop
        return loop.running and tick_gap_s(loop) < loop.stall_s

    def send_stopping(self) -> None:
        if self.stopping_sent or self.loop.handed_over:
            return  # a restart in place is a reload, not a stop
        self.stopping_sent = True
        reason = self.stop_reason or self.loop.stopped_reason or "shutting down"
        self.notifier.stopping(f"stopping ({reason}): ramping to the safe state and "
                               "finalising the recording")

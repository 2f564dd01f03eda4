"""What systemd is told (one job of the service keeper, `pamd.daemon.service.keeper`):
`READY=1` once the loop ticks (even with a device missing: the rig is then in FAULT
and STATUS says why), `WATCHDOG=1` while the loop ticks on time (a stalled loop gets
no pings and systemd restarts it; a FAULT is not a stall), `STATUS=` with the
supervisor's state and reason, `STOPPING=1` on shutdown.

**The pings prove the loop alive, nothing else.** They come from a thread of their
own (`Pinger`, "pamd-watchdog"), which sends one every quarter watchdog period while
the loop has completed a tick within its stall limit, and asks again every
`RETRY_S` while it has not (so one late check never costs a whole period). What the
main thread does (a reload's file read and checked, the status, a collection's files)
never delays them, and a reload is invisible to systemd's watchdog. A daemon
restarted in place (`pamd.daemon.service.restart`), whose watchdog systemd keeps running
through its start, is pinged through that start too, for at most
`STARTUP_WATCHDOG_S`, and so is the old daemon between the loop's hand-over and the
exec. Outside systemd the notifier is disabled and this sends nothing.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from pamd.daemon.service.notify import Notifier
from pamd.daemon.service.ports import KeptLoop, tick_gap_s

log = logging.getLogger("pamd")

#: How long a restarted daemon's start (or an old one's hand-over before its exec) is
#: pinged: imports, drivers, the io process, with room for a busy machine. A start
#: that takes longer gets no more pings, and systemd restarts it.
STARTUP_WATCHDOG_S = 60.0
#: After a check that found the loop late, the pinger asks again this soon.
RETRY_S = 0.02


class Pinger:
    """`WATCHDOG=1` from a thread of its own every `interval_s` while `alive()` says
    so (asked again every RETRY_S while it does not). `start()` once; `stop()` ends it."""

    def __init__(self, notifier: Notifier, interval_s: float,
                 alive: Callable[[], bool]) -> None:
        self.notifier = notifier
        self.interval_s = interval_s
        self.alive = alive
        self.pings = 0
        self.last_ping = time.monotonic()  # the last ping, or the pinger's start
        self.withheld = False  # the last check found the loop late
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="pamd-watchdog", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(1.0)

    def _run(self) -> None:
        wait = 0.0
        while not self._stop.wait(wait):
            if self.alive():
                self.notifier.watchdog()
                self.pings += 1
                self.last_ping = time.monotonic()
                self.withheld = False
                wait = self.interval_s
            else:
                self.withheld = True
                wait = RETRY_S


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
        self._withholding = False
        # a daemon restarted in place: systemd's watchdog runs through its start
        self._bounded_since = time.monotonic() if notifier.restarted else None
        interval = notifier.ping_interval_s
        self.pinger: Pinger | None = None
        if interval is not None:
            # due every half period: sent every quarter, so that one late wake-up of
            # this thread never makes a gap of more than three quarters
            self.pinger = Pinger(notifier, interval / 2.0, self.alive)
            self.pinger.start()

    @property
    def pings(self) -> int:
        return 0 if self.pinger is None else self.pinger.pings

    def stop_requested(self, reason: str) -> None:
        """Daemon.stop() (possibly from a signal handler): only remember it."""
        if self.stop_reason is None:
            self.stop_reason = reason

    def ready_again(self) -> None:
        """A reload is over (applied, deferred or refused): READY=1 with the status."""
        self.last_status = self.status_text()
        self.notifier.ready(self.last_status)

    def handing_over(self) -> None:
        """The loop is asked to hand over for a restart in place: from its end to the
        exec the pings go on, bounded (the new daemon's start is pinged by itself)."""
        self._bounded_since = time.monotonic()

    def alive(self) -> bool:
        """What the pings say (the pinger's thread asks): the loop ticks on time; or, in
        a bounded start or hand-over (see the module's doc), within its bound."""
        loop = self.loop
        if loop.running and not loop.handed_over and self.ready_sent:
            return tick_gap_s(loop) < loop.stall_s
        since = self._bounded_since
        return since is not None and time.monotonic() - since < STARTUP_WATCHDOG_S and (
            loop.handed_over or not loop.stopped_reason)

    def service(self) -> None:
        """Every 50 ms: READY once, STATUS when it changes, STOPPING once; what the
        pinger withholds, said."""
        n = self.notifier
        loop = self.loop
        status = self.status_text()
        if not self.ready_sent and loop.running and loop.timing.ticks > 0:
            self.ready_sent = True
            self._bounded_since = None  # the loop's ticks prove it alive from now on
            self.last_status = status
            n.ready(status)
        elif status != self.last_status:
            self.last_status = status
            n.status(status)
        if self.stop_reason is not None or loop.stopped_reason:
            self.send_stopping()
        pinger = self.pinger
        if pinger is None or not self.ready_sent or not loop.running:
            return
        late = time.monotonic() - pinger.last_ping > 2.0 * pinger.interval_s  # was due
        if pinger.withheld and late and not self._withholding:
            self._withholding = True
            log.error("the loop has not completed a tick for %.0f ms: watchdog pings "
                      "withheld (systemd restarts pamd if this lasts)",
                      1000 * tick_gap_s(loop))
        elif self._withholding and not pinger.withheld:
            self._withholding = False
            log.warning("the loop ticks on time again: watchdog pings resumed")

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

    def close(self) -> None:
        """The daemon is closing: no more pings (a restart in place's exec, or the end)."""
        if self.pinger is not None:
            self.pinger.stop()

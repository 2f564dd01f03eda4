"""The systemd notify protocol (sd_notify), a few lines over a datagram socket.

systemd passes `NOTIFY_SOCKET` (a path, or an abstract name starting with '@') and,
with `WatchdogSec=`, `WATCHDOG_USEC` (and `WATCHDOG_PID`, the process it expects
pings from). A message is newline-separated `KEY=VALUE` lines in one datagram:
`READY=1`, `STATUS=...`, `WATCHDOG=1`, `WATCHDOG_USEC=...`, `STOPPING=1`,
`RELOADING=1`.

Outside systemd (no `NOTIFY_SOCKET`) a `Notifier` is disabled and sends nothing.
Sending never raises: a notify socket that went away is logged once, and the
daemon goes on controlling the rig.
"""

from __future__ import annotations

import logging
import os
import socket
import time
from collections.abc import Mapping

log = logging.getLogger("pamd")

#: Set by a restart in place to the PID it executes itself as (the same PID).
RESTARTED_ENV = "PAMD_RESTARTED_IN_PLACE"


def socket_address(value: str) -> str | bytes:
    """The address to send to: abstract names ('@name') become b'\\0name'."""
    if value.startswith("@"):
        return b"\0" + value[1:].encode()
    return value


class Notifier:
    """Sends notify messages to `address` (None: disabled, every call a no-op).

    `watchdog_s` is the watchdog timeout systemd enforces (None: no watchdog);
    pings are due every half of it (`ping_interval_s`)."""

    def __init__(self, address: str | None, watchdog_s: float | None = None,
                 restarted: bool = False) -> None:
        """`restarted`: this process is a daemon restarted in place (`pamd.service.
        restart`), whose watchdog systemd keeps running through its start."""
        self.address = address
        self.watchdog_s = watchdog_s
        self.restarted = restarted
        self._sock: socket.socket | None = None
        self._failed = False
        if address:
            self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)

    @classmethod
    def from_environ(cls, environ: Mapping[str, str] | None = None) -> Notifier:
        """The notifier systemd asked for through the environment (or a disabled one).

        `WATCHDOG_USEC` counts only if `WATCHDOG_PID` is unset or this process.
        `RESTARTED_ENV` (set by a restart in place for the process it executes) says
        this is that process; it is taken out of `os.environ`, so that nothing this
        process starts inherits it."""
        env = os.environ if environ is None else environ
        restarted = env.get(RESTARTED_ENV) == str(os.getpid())
        if environ is None:
            os.environ.pop(RESTARTED_ENV, None)
        address = env.get("NOTIFY_SOCKET") or None
        if address is not None and not (address.startswith("/") or address.startswith("@")):
            log.warning("NOTIFY_SOCKET=%r is neither a path nor an abstract name; "
                        "not notifying systemd", address)
            address = None
        watchdog_s = None
        usec = env.get("WATCHDOG_USEC", "")
        pid = env.get("WATCHDOG_PID", "")
        if usec.isdigit() and int(usec) > 0 and (not pid or pid == str(os.getpid())):
            watchdog_s = int(usec) / 1e6
        return cls(address, watchdog_s, restarted)

    @property
    def enabled(self) -> bool:
        return self._sock is not None

    @property
    def ping_interval_s(self) -> float | None:
        """How often WATCHDOG=1 is due (half the watchdog timeout), or None."""
        if self.watchdog_s is None or not self.enabled:
            return None
        return self.watchdog_s / 2.0

    def send(self, *lines: str) -> bool:
        """Send one datagram of `KEY=VALUE` lines; False if disabled or it failed."""
        if self._sock is None or self.address is None:
            return False
        data = "\n".join(lines).encode("utf-8", "replace")
        try:
            self._sock.sendto(data, socket_address(self.address))
        except OSError as exc:
            if not self._failed:
                self._failed = True
                log.warning("cannot notify systemd at %s: %s", self.address, exc)
            return False
        if self._failed:
            self._failed = False
            log.info("notifying systemd at %s again", self.address)
        return True

    # -- the messages pamd sends ----------------------------------------------------
    def ready(self, status: str) -> bool:
        """`READY=1` with the status; with a watchdog also `WATCHDOG_USEC=`, which sets
        back a timeout widened for a restart in place (`pamd.daemon.service.restart`)."""
        watchdog = () if self.watchdog_s is None else (
            f"WATCHDOG_USEC={round(self.watchdog_s * 1e6)}",)
        return self.send("READY=1", f"STATUS={one_line(status)}", *watchdog)

    def status(self, status: str) -> bool:
        return self.send(f"STATUS={one_line(status)}")

    def watchdog(self) -> bool:
        return self.send("WATCHDOG=1")

    def reloading(self) -> bool:
        usec = time.clock_gettime_ns(time.CLOCK_MONOTONIC) // 1000
        return self.send("RELOADING=1", f"MONOTONIC_USEC={usec}")

    def stopping(self, status: str) -> bool:
        return self.send("STOPPING=1", f"STATUS={one_line(status)}")

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def one_line(text: str, limit: int = 400) -> str:
    """A STATUS= value: one line, not too long."""
    flat = " ".join(text.split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."

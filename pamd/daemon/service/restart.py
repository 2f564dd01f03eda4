"""Restart in place: how a reload applies changes that reopen the devices.

A new config that changes the drivers, which muscles there are and how their
signals are wired, the loop's rate or clock, the recording or the rig id cannot be
applied to a running loop. Once the rig is at rest (IDLE, no profile, a stop's ramp
to the safe state completed) the loop ends at a tick boundary
without ramping to the safe state (`Loop.request_handover`): the regulators keep
the pressure they were given; the recording is finalised and the io process
leaves Zenoh; the drivers are closed (closing writes nothing). Then the process
executes `pamd run` again with its standing options: the same PID, so systemd
(`Type=notify`, `NotifyAccess=main`) keeps tracking it, and the new daemon starts
like every start: it reads every sensor before it writes, holds the measured
pressure, in pressure mode, and runs no profile. systemd hears `RELOADING=1`
before and `READY=1` from the new daemon once it ticks; the watchdog is widened
for the few seconds of start-up and set back with that `READY=1`, and the old
daemon's hand-over and the new daemon's start are pinged too (`pamd.daemon.service.watchdog`,
bounded by `STARTUP_WATCHDOG_S`).

Signals: SIGTERM, SIGINT and SIGHUP are blocked from the exec until the new daemon
has its handlers (`unblock_signals`): one that arrives meanwhile waits for it and is
not lost, and a stop that came while this daemon was closing is sent on, so the
new daemon starts, reads, and then stops to the safe state as asked.

What is not a standing option is dropped: a profile, a mode or a muscle to apply
them to were commands of the first start, not configuration; a `--duration` goes
on with what is left of it.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
from multiprocessing import resource_tracker
from typing import NoReturn

from pamd.daemon.service.notify import RESTARTED_ENV, Notifier
from pamd.daemon.service.watchdog import STARTUP_WATCHDOG_S
from pamd.loop.commands import offload

log = logging.getLogger("pamd")

# `pamd run` options that describe the daemon rather than what it was first asked to
# do: (argparse dest, flag, takes a value)
STANDING_OPTIONS: tuple[tuple[str, str, bool], ...] = (
    ("config", "--config", True),
    ("clock", "--clock", True),
    ("rate_hz", "--rate-hz", True),
    ("json", "--json", False),
    ("note", "--note", True),
    ("load_kg", "--load-kg", True),
    ("state_dir", "--state-dir", True),
    ("record", "--record", True),
    ("no_record", "--no-record", False),
    ("name", "--name", True),
    ("no_telemetry", "--no-telemetry", False),
    ("zenoh_config", "--zenoh-config", True),
    ("listen", "--listen", True),
    ("allow_cleartext", "--allow-cleartext", False),
    ("foxglove", "--foxglove", True),
    ("model", "--model", True),
    ("stay_on_fault", "--stay-on-fault", False),
    ("end_on_fault", "--end-on-fault", False),
)


def run_argv(args: argparse.Namespace, remaining_s: float | None) -> list[str]:
    """The `pamd run` command line of the restarted daemon."""
    argv = [sys.executable, "-m", "pamd", "run"]
    for dest, flag, takes_value in STANDING_OPTIONS:
        value = getattr(args, dest, None)
        if dest == "load_kg" and value:  # --load-kg, parsed: [[(muscle | None, kg), ...]]
            argv += [flag, ",".join(f"{kg!r}" if name is None else f"{name}={kg!r}"
                                    for group in value for name, kg in group)]
        elif takes_value and value not in (None, ""):
            argv += [flag, str(value)]
        elif (not takes_value and value) or (dest == "record" and value == ""):
            argv.append(flag)  # a switch; or --record without a directory
    if remaining_s is not None:
        argv += ["--duration", repr(remaining_s)]
    return argv


HELD_SIGNALS = frozenset({signal.SIGTERM, signal.SIGINT, signal.SIGHUP})


def unblock_signals() -> None:
    """In `pamd run`, once its handlers are installed: deliver what a restart in
    place held back (a no-op on an ordinary start)."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, HELD_SIGNALS)


def restart_in_place(argv: list[str], reason: str, stop_received: bool) -> NoReturn:
    """Replace this process by `argv` (same PID). Call only once the loop has handed
    over and the daemon is closed. `stop_received`: a stop signal came after the
    loop had handed over; the new daemon gets it as soon as it can act on it."""
    signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS)
    main = threading.main_thread().ident
    if stop_received and main is not None:
        signal.pthread_kill(main, signal.SIGTERM)  # pending across the exec
    log.warning("restarting in place (pid %d) to apply the new config: %s", os.getpid(),
                reason)
    _stop_resource_tracker()
    offload.stop()  # the file reader's forkserver, reaped (the new daemon starts its own)
    notifier = Notifier.from_environ()
    if notifier.watchdog_s is not None:  # widened; the new daemon's READY=1 sets it back
        notifier.send("WATCHDOG=1", f"WATCHDOG_USEC={int(STARTUP_WATCHDOG_S * 1e6)}")
    notifier.close()
    os.environ[RESTARTED_ENV] = str(os.getpid())  # the new daemon pings through its start
    for handler in logging.getLogger().handlers + log.handlers:
        handler.flush()
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(argv[0], argv)


def _stop_resource_tracker() -> None:
    """multiprocessing's resource tracker (a child started with the io process) would
    see its pipe close at the exec, exit, and stay a zombie of the new daemon: stop
    and reap it now (the new daemon starts its own)."""

    tracker = getattr(resource_tracker, "_resource_tracker", None)  # private, 3.8+
    stop = getattr(tracker, "_stop", None)
    if stop is None:
        return
    try:
        stop()
    except Exception as exc:  # noqa: BLE001 - a leftover zombie is no reason not to restart
        log.debug("resource tracker not stopped: %s", exc)

"""Test hooks of `pamd run`, for the service tests only: each is off unless its
environment variable is set, and says loudly when it is on. They live with the tests,
not in pamd (issue 41): `python tests/service/testhooks.py run ARGS` is `pamd run ARGS`
with the hooks installed on its daemon as it is built (`DaemonProcess` runs it so when
a test's environment asks for a hook).

`PAMD_TEST_STALL_LOOP="TICKS:SECONDS"` makes the loop's thread sleep SECONDS once,
in tick number TICKS (a hung driver call, say), so a test can see the watchdog
pings stop while the main thread is alive. SIGSTOP cannot do it: it stops the
whole process, the pinger with it. `PAMD_TEST_SLOW_RELOAD="SECONDS"` makes a reload's
read SECONDS longer.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

log = logging.getLogger("pamd")
P = ParamSpec("P")
T = TypeVar("T")

STALL_ENV = "PAMD_TEST_STALL_LOOP"
#: `PAMD_TEST_SLOW_RELOAD="SECONDS"`: a reload's file takes SECONDS longer to read (a
#: large config or model file on a busy PC), so a test can see that neither the pings
#: nor the tick records wait for it.
SLOW_RELOAD_ENV = "PAMD_TEST_SLOW_RELOAD"


class StallOnce:
    """A 'stepper' the loop advances each tick; it sleeps `seconds` in tick `at_tick`."""

    steps_with_loop = True

    def __init__(self, at_tick: int, seconds: float) -> None:
        self.at_tick = at_tick
        self.seconds = seconds
        self.ticks = 0

    def advance(self, dt_s: float) -> None:
        self.ticks += 1
        if self.ticks == self.at_tick:
            time.sleep(self.seconds)


def _slowed(read: Callable[P, T], seconds: float) -> Callable[P, T]:
    def slow(*args: P.args, **kwargs: P.kwargs) -> T:
        time.sleep(seconds)
        return read(*args, **kwargs)
    return slow


# Any: the Daemon, whose controller gets a stepper that is no driver
def install(daemon: Any, environ: dict[str, str] | None = None) -> list[str]:
    """Install the hooks the environment asks for; returns their descriptions."""
    env = os.environ if environ is None else environ
    active: list[str] = []
    spec = env.get(STALL_ENV)
    if spec:
        ticks, _, seconds = spec.partition(":")
        hook = StallOnce(int(ticks), float(seconds))
        daemon.ctrl.steppers.append(hook)
        active.append(f"{STALL_ENV}: the loop stalls {hook.seconds:g} s in tick {hook.at_tick}")
    slow = env.get(SLOW_RELOAD_ENV)
    if slow:
        reloader = daemon.keeper.reloader
        reloader.read = _slowed(reloader.read, float(slow))
        active.append(f"{SLOW_RELOAD_ENV}: a reload's file takes {float(slow):g} s longer "
                      "to read")
    for what in active:
        log.warning("TEST HOOK ACTIVE (never on a rig): %s", what)
    return active


def main() -> int:
    """`pamd run` (`python -m pamd`), each daemon built with the hooks installed."""
    from pamd.__main__ import main as pamd_main
    from pamd.daemon.daemon import Daemon

    built = Daemon.__init__

    def hooked(self: Daemon, *args: Any, **kwargs: Any) -> None:  # Any: as Daemon's own
        built(self, *args, **kwargs)
        install(self)
    Daemon.__init__ = hooked  # type: ignore[method-assign]
    sys.argv[0] = str(Path(pamd_main.__code__.co_filename))  # as `python -m pamd` says
    return pamd_main()


if __name__ == "__main__":
    raise SystemExit(main())

"""Fixtures of the driver tests (helpers live in pamd.emulate.testing)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import pytest

from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.emulate.rig import EmulatedRig
from pamd.emulate.testing import AioThread


@pytest.fixture
def aio() -> Iterator[AioThread]:
    t = AioThread()
    yield t
    t.stop()


@contextlib.contextmanager
def daemon_on_emulated_rig(cfg: LoadedConfig) -> Iterator[tuple[EmulatedRig, Daemon]]:
    """The emulated rig of `cfg` in this process and a daemon started against it; both
    stopped at the end (the daemon first, given 40 s to reach its safe state)."""
    rig = EmulatedRig(cfg)
    rig.start()
    daemon = Daemon(cfg)
    daemon.start()
    try:
        yield rig, daemon
    finally:
        daemon.stop("test finished")
        daemon.wait(timeout_s=40)
        daemon.close()
        rig.stop()

"""Best-effort real-time set-up for the loop's thread: SCHED_FIFO, mlockall, CPU
affinity, timer slack, /dev/cpu_dma_latency. Each step the OS refuses becomes a
warning that says how to allow it; none is fatal."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import struct
from collections.abc import Callable
from typing import IO

from pamd.config.schema import RealtimeConfig

PR_SET_TIMERSLACK = 29
MCL_CURRENT, MCL_FUTURE = 1, 2


def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("c")
    return ctypes.CDLL(name, use_errno=True) if name else None


class RealtimeSession:
    """Applies the settings to the calling thread; `close()` releases the DMA latency
    request. `warnings` lists what could not be applied."""

    def __init__(self) -> None:
        self.warnings: list[str] = []
        self.applied: list[str] = []
        self._dma: IO[bytes] | None = None

    def apply(self, cfg: RealtimeConfig, warn: Callable[[str], None]) -> None:
        if not cfg.enabled:
            return
        libc = _libc()

        def refused(what: str, exc: BaseException | str, how: str) -> None:
            msg = f"real-time: could not {what} ({exc}); {how}"
            self.warnings.append(msg)
            warn(msg)

        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(cfg.priority))
            self.applied.append(f"SCHED_FIFO {cfg.priority}")
        except (OSError, AttributeError) as exc:
            refused("set SCHED_FIFO", exc, "allow it with LimitRTPRIO= (systemd) or "
                    "CAP_SYS_NICE; the loop runs at normal priority")
        if cfg.lock_memory and libc is not None:
            if libc.mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
                refused("lock memory", os.strerror(ctypes.get_errno()),
                        "raise LimitMEMLOCK= / ulimit -l")
            else:
                self.applied.append("mlockall")
        if cfg.cpu is not None:
            try:
                os.sched_setaffinity(0, {cfg.cpu})
                self.applied.append(f"cpu {cfg.cpu}")
            except OSError as exc:
                refused(f"pin to CPU {cfg.cpu}", exc, "check loop.realtime.cpu")
        if libc is not None:
            if libc.prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(cfg.timer_slack_ns), 0, 0, 0) != 0:
                refused("set timer slack", os.strerror(ctypes.get_errno()), "ignored")
            else:
                self.applied.append(f"timer slack {cfg.timer_slack_ns} ns")
        if cfg.cpu_dma_latency:
            try:
                fh = open("/dev/cpu_dma_latency", "wb", buffering=0)  # noqa: SIM115
                fh.write(struct.pack("i", 0))
                self._dma = fh
                self.applied.append("cpu_dma_latency 0")
            except OSError as exc:
                refused("hold /dev/cpu_dma_latency at 0", exc.strerror or exc,
                        "needs write access to /dev/cpu_dma_latency")

    def close(self) -> None:
        if self._dma is not None:
            self._dma.close()
            self._dma = None

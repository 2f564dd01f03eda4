"""Best-effort real-time set-up for the loop's thread: SCHED_FIFO, mlockall, CPU
affinity, timer slack, /dev/cpu_dma_latency. Each step the OS refuses becomes a
warning that says how to allow it; none is fatal.

The other threads of the loop's process (the main thread, the drivers' I/O threads,
any a library starts) go to SCHED_FIFO too, at `other_threads_priority`, below the
loop's. They share the interpreter lock with the loop's thread: when the loop wakes
and one of them holds the lock, the loop waits until that thread runs again and lets
go. At normal priority that thread waits for a CPU behind every normal-priority
process on the machine (CPU hogs, package installs, test runs), so the real-time loop
waited behind them too: priority inversion through the lock. Measured on a shared
2-core machine beside two CPU hogs (bench/shared_machine.py, and a 20 s loop with a
main thread that runs 1-2 ms of Python every 50 ms): 112 wake-ups later than 10 ms,
the worst 191 ms, with no time spent on a run queue by the loop's thread (it slept on
the lock); with the main thread at SCHED_FIFO below the loop's, the worst was 1.0 ms.
A thread raised here keeps SCHED_RESET_ON_FORK, so nothing it starts inherits the
real-time policy; threads started later are raised by `raise_others()` again (the
service keeper calls it every second), and `close()` puts each back as it was.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import struct
import threading
from collections.abc import Callable
from typing import IO

from pamd.config.schema import RealtimeConfig

PR_SET_TIMERSLACK = 29
MCL_CURRENT, MCL_FUTURE = 1, 2
TASKS = "/proc/self/task"
RESET_ON_FORK = getattr(os, "SCHED_RESET_ON_FORK", 0x40000000)
NORMAL_POLICIES = (os.SCHED_OTHER, getattr(os, "SCHED_BATCH", 3), getattr(os, "SCHED_IDLE", 5))


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
        self._loop_tid: int | None = None
        self._others_priority: int | None = None
        self._raised: dict[int, tuple[int, int]] = {}  # tid -> (policy, priority) before
        self._refused_others = False
        self._lock = threading.Lock()  # raise_others (main thread) against close (loop's)

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
            self._loop_tid = threading.get_native_id()
            if cfg.other_threads_priority is not None:  # below the loop's (1 beside 1)
                self._others_priority = max(1, min(cfg.other_threads_priority,
                                                   cfg.priority - 1))
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
        if self._others_priority is not None:
            n = self.raise_others(warn)
            if not self._refused_others:
                self.applied.append(f"other threads SCHED_FIFO {self._others_priority} "
                                    f"({n} now)")

    def raise_others(self, warn: Callable[[str], None] | None = None) -> int:
        """Put every thread of this process that runs at normal priority (not the
        loop's) on SCHED_FIFO at `other_threads_priority`; returns how many threads
        were raised by now. Any thread may call it (a scan of /proc/self/task, no
        lock); nothing happens unless the loop's thread got SCHED_FIFO."""
        with self._lock:
            return self._raise_others(warn)

    def _raise_others(self, warn: Callable[[str], None] | None) -> int:
        prio = self._others_priority
        if prio is None:
            return 0
        try:
            tids = [int(t) for t in os.listdir(TASKS)]
        except OSError:
            return len(self._raised)
        for tid in tids:
            if tid == self._loop_tid or tid in self._raised:
                continue
            try:
                policy = os.sched_getscheduler(tid)
                if policy & ~RESET_ON_FORK not in NORMAL_POLICIES:
                    continue  # already real-time (raised by someone else): leave it
                before = os.sched_getparam(tid).sched_priority
                os.sched_setscheduler(tid, os.SCHED_FIFO | RESET_ON_FORK,
                                      os.sched_param(prio))
            except ProcessLookupError:
                continue  # ended meanwhile
            except OSError as exc:
                if not self._refused_others:
                    self._refused_others = True
                    msg = (f"real-time: could not raise the other threads of the loop's "
                           f"process to SCHED_FIFO {prio} ({exc}); a thread that holds the "
                           "interpreter lock at normal priority can delay the loop behind "
                           "every busy process (priority inversion)")
                    self.warnings.append(msg)
                    if warn is not None:
                        warn(msg)
                continue
            self._raised[tid] = (policy, before)
        return len(self._raised)

    def close(self) -> None:
        if self._dma is not None:
            self._dma.close()
            self._dma = None
        with self._lock:
            self._others_priority = None
            raised, self._raised = self._raised, {}
        for tid, (policy, prio) in raised.items():
            # back as it was (a library daemon's caller keeps its normal priority)
            with contextlib.suppress(OSError):
                os.sched_setscheduler(tid, policy, os.sched_param(prio))

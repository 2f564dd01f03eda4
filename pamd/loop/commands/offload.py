"""A file a command names is read and parsed in a short-lived child process, never in
the loop's process: the parse of a large file is one long C call (`json.loads` of an
8 MiB model takes 0.7-1.3 s on a busy PC) that holds the interpreter lock the loop's
thread needs, so done in the daemon it stalls the loop however it is threaded.

`run_isolated(fn, *args)` runs `fn` in a child forked from the `forkserver` (a clean,
single-threaded process that has imported pamd once: a job starts in milliseconds,
not a second) at the daemon's own priority, waits for it without
holding the interpreter lock, and returns its result, pickled back: a small object
(a checked model, a plan), so taking it in costs the loop's process little (measured:
`bench/files_model_load.py`). The child is killed past `time_limit_s`, and the
refusal says so; a `CommandRefused` or `PamdError` it raises comes back as it is; any
other failure (even the child's death: a hostile file that exhausts memory) is a
refusal naming the file's role and the failure's class, never its contents.

The caller's thread blocks (waiting in a pipe, the lock released): the daemon's main
thread hands the wait to a worker thread (`Preparer`) so that status and other
commands go on meanwhile.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import pickle
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from multiprocessing import forkserver
from multiprocessing.connection import Connection
from typing import TypeVar

from pamd.wire.errors import CommandRefused, PamdError

T = TypeVar("T")

#: The child's priority relative to the daemon: the same. What keeps the loop on time
#: is the separate process (no interpreter lock shared), not a lower priority; a niced
#: child on a machine busy with other work starves, and a small plan's verdict with it.
CHILD_NICE = 0
#: Largest result taken back (bytes): a checked model or plan is far smaller.
MAX_RESULT_BYTES = 4 << 20

_CTX = multiprocessing.get_context("forkserver")
_CTX.set_forkserver_preload(["pamd.loop.commands.model_file", "pamd.loop.experiment.plan"])
_lock = threading.Lock()


#: How long the forkserver may take to start and import pamd (a second of a core when
#: the machine is idle, many on one busy with other work); not a file's time.
WARM_UP_LIMIT_S = 120.0
_warm = threading.Event()
_warming = threading.Lock()


def warm_up(time_limit_s: float = WARM_UP_LIMIT_S) -> None:
    """Start the forkserver now and wait until it has imported pamd (about a second of
    a core) and forked a first child, so that the first command that names a file
    does not wait for it (the daemon does this in a worker thread as it starts)."""
    with _warming:  # a second caller waits for the first one's warm-up
        if _warm.is_set():
            return
        with _lock:
            forkserver.ensure_running()
        _run(int, (), time_limit_s, "the file reader's start")
        _warm.set()


def stop() -> None:
    """Stop the forkserver and reap it, if it runs (before a restart in place: at the
    exec it would see its pipe close, exit, and stay a zombie of the new daemon)."""
    _warm.clear()  # the next job starts (and warms) a new one
    server = getattr(forkserver, "_forkserver", None)  # private, 3.4+
    stop_server = getattr(server, "_stop", None)
    if stop_server is None:
        return
    with _lock, contextlib.suppress(Exception):  # a leftover zombie: no reason not to go on
        stop_server()


def _child(conn: Connection, fn: Callable[..., object], args: tuple[object, ...]) -> None:
    if CHILD_NICE:
        with contextlib.suppress(OSError):
            os.nice(CHILD_NICE)
    # (True, result) | (False, an exception that says it all) | (False, what went wrong)
    out: tuple[bool, object]
    try:
        out = (True, fn(*args))
    except (CommandRefused, PamdError) as exc:
        out = (False, exc)
    except RecursionError:
        out = (False, "nested too deep to read")
    except MemoryError:
        out = (False, "too large to read (out of memory)")
    except Exception as exc:  # the parent refuses with the class, never the contents
        out = (False, f"it could not be read ({exc.__class__.__name__})")
    try:
        conn.send(out)
    except Exception as exc:  # an unpicklable result
        conn.send((False, f"its result could not be handed back ({exc.__class__.__name__})"))
    conn.close()


def run_isolated(fn: Callable[..., T], *args: object, time_limit_s: float, what: str) -> T:
    """`fn(*args)` in a child process (see the module doc); `what` names the job in a
    refusal ("model file 'x.json'"). `time_limit_s` is the job's, its child's start
    included; a forkserver not yet warm is warmed first, outside that limit (its start
    is not the file's cost: on a busy machine it alone can take longer than a file's
    whole limit, which would refuse a good file)."""
    if not _warm.is_set():
        warm_up()
    return _run(fn, args, time_limit_s, what)


def _run(fn: Callable[..., T], args: tuple[object, ...], time_limit_s: float, what: str) -> T:
    deadline = time.monotonic() + time_limit_s  # the child's start included
    reader, writer = _CTX.Pipe(duplex=False)
    with _lock:  # one start at a time: the forkserver's socket is shared
        proc = _CTX.Process(target=_child, args=(writer, fn, args), daemon=True,
                            name="pamd-file")
        proc.start()
    writer.close()
    try:
        if not reader.poll(max(0.0, deadline - time.monotonic())):
            raise CommandRefused(f"{what}: not read within {time_limit_s:g} s (the limit "
                                 "for a file a command names); a smaller file reads faster")
        try:
            blob = reader.recv_bytes(MAX_RESULT_BYTES)
        except OSError:
            raise CommandRefused(f"{what}: larger than {MAX_RESULT_BYTES} bytes once "
                                 "read") from None
        except EOFError:
            proc.join(1.0)
            raise CommandRefused(f"{what}: the process reading it ended (exit code "
                                 f"{proc.exitcode}) without an answer") from None
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(5.0)
        reader.close()
        proc.close()
    ok, value = pickle.loads(blob)
    if not ok:
        if isinstance(value, BaseException):
            raise value
        raise CommandRefused(f"{what}: {value}")
    result: T = value  # what fn returned, unpickled (the child ran fn: its type is T)
    return result


class Preparer:
    """A worker thread of the daemon's main process for the waits of `run_isolated`:
    `submit(fn, ...)` returns a Future the main thread polls (`done()`), so a
    command's file is read while status and other commands go on."""

    def __init__(self) -> None:
        self._pool: ThreadPoolExecutor | None = None

    def submit(self, fn: Callable[..., T], *args: object) -> Future[T]:
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="pamd-prepare")
        return self._pool.submit(fn, *args)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

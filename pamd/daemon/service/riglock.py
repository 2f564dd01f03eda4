"""Locks guard what a run opens, not the machine: each serial port, fieldbus device,
CAN channel and state directory a daemon opens is locked with an exclusive,
non-blocking `flock` on a lock file named for it (`pamd-serial_port__dev_ttyUSB0.lock`),
taken before anything opens and held for the daemon's life. The kernel releases it
when the process ends, however it ends (SIGKILL, a crash): there is never a stale
lock to clean up. A second daemon that would open one of them (`pamd run`, `pamd
tune`, a collection) is refused with what and who holds it: the holder writes its
pid, command line, rig and start time into the file. A simulation opens nothing: a
virtual-clock run of the simulated rig takes no lock at all (and keeps no state, see
pamd.daemon.service.state), so simulations never refuse each other.

Where the lock files are (the first that applies):

1. `PAMD_LOCK_DIR` (tests give each test its own; a lab with its own convention);
2. `RUNTIME_DIRECTORY` (systemd sets it: `RuntimeDirectory=pamd`, i.e. /run/pamd);
3. /run/pamd when it exists (made at boot by systemd/pamd.tmpfiles.conf, mode 1777):
   so a `pamd run` started by hand and the service see each other's locks;
4. `$XDG_RUNTIME_DIR/pamd`, else `<tmp>/pamd-<uid>` (no service installed).

A lock file the daemon cannot write (another user's, in /run/pamd) is still locked,
opened read-only: the lock is what matters, the holder's note is a courtesy.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import re
import sys
import tempfile
import time
from collections.abc import Sequence
from typing import IO

from pamd.wire.errors import PamdError

LOCK_DIR_ENV = "PAMD_LOCK_DIR"
SYSTEM_LOCK_DIR = "/run/pamd"


class RigBusy(PamdError):
    """Another daemon holds what this one would open: nothing was opened."""

    exit_code = 8


def lock_dir() -> str:
    """The directory of the rig lock files (see the module's docstring)."""
    for env in (LOCK_DIR_ENV, "RUNTIME_DIRECTORY"):
        value = os.environ.get(env)
        if value:
            return value.split(":")[0]
    if os.path.isdir(SYSTEM_LOCK_DIR):
        return SYSTEM_LOCK_DIR
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg and os.path.isdir(xdg) and os.access(xdg, os.W_OK):
        return os.path.join(xdg, "pamd")
    return os.path.join(tempfile.gettempdir(), f"pamd-{os.getuid()}")


def lock_path(resource: str, directory: str | None = None) -> str:
    """The lock file of `resource` (a name such as "serial port /dev/ttyUSB0"): its
    characters that cannot be in a file name become '_'; a long one is cut and keeps a
    hash of the whole, so two resources never share a file."""
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", resource) or "rig"
    if len(safe) > 120:
        digest = hashlib.sha256(resource.encode()).hexdigest()[:12]
        safe = f"{safe[:100]}-{digest}"
    return os.path.join(directory or lock_dir(), f"pamd-{safe}.lock")


def holder(path: str) -> dict[str, object]:
    """What the holder wrote into the lock file ({} if nothing readable)."""
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.loads(fh.read() or "{}")
    except (OSError, ValueError):
        return {}
    return doc if isinstance(doc, dict) else {}


def command_line() -> str:
    """This process's command as the operator typed it (`pamd run ...`, also for
    `python -m pamd run ...`)."""
    argv = sys.argv or [""]
    first = os.path.basename(argv[0])
    if first == "pamd" or argv[0].endswith(os.path.join("pamd", "__main__.py")):
        return " ".join(["pamd", *argv[1:]])
    return " ".join(argv)


def describe_holder(info: dict[str, object]) -> str:
    pid = info.get("pid", "?")
    cmd = info.get("command") or "an unknown command"
    since = info.get("since") or "an unknown time"
    return f"pid {pid} ({cmd}), since {since}"


class ResourceLock:
    """The lock of one resource. `acquire()` (RigBusy if held), `release()`."""

    def __init__(self, resource: str, rig_id: str = "", directory: str | None = None) -> None:
        self.resource = resource
        self.rig_id = rig_id
        self.path = lock_path(resource, directory)
        self._fh: IO[str] | None = None

    @property
    def held(self) -> bool:
        return self._fh is not None

    def acquire(self, what: str = "") -> None:
        """Take the lock or raise RigBusy naming the holder and what to do."""
        if self._fh is not None:
            return
        fh, writable = self._open()
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            fh.close()
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            raise RigBusy(self._busy_message()) from None
        if writable:
            note = {"pid": os.getpid(), "command": what or command_line(),
                    "since": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "rig_id": self.rig_id,
                    "resource": self.resource}
            with contextlib.suppress(OSError):
                fh.seek(0)
                fh.truncate()
                fh.write(json.dumps(note) + "\n")
                fh.flush()
        self._fh = fh

    def release(self) -> None:
        """Let it go (closing the file releases the lock; the file stays)."""
        fh, self._fh = self._fh, None
        if fh is not None:
            with contextlib.suppress(OSError):
                fh.seek(0)
                fh.truncate()
            fh.close()

    def _open(self) -> tuple[IO[str], bool]:
        directory = os.path.dirname(self.path)
        try:
            os.makedirs(directory, exist_ok=True)
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            with contextlib.suppress(OSError):  # readable by all, whatever the umask
                os.fchmod(fd, 0o644)
        except PermissionError:
            try:  # another user's lock file: lock it read-only
                return open(self.path, encoding="utf-8"), False  # noqa: SIM115
            except OSError as exc:
                raise RigBusy(f"{self.resource}: its lock file {self.path} cannot be "
                              f"opened ({exc.strerror}): let this user write {directory} "
                              f"or point {LOCK_DIR_ENV} at a directory it can") from None
        except OSError as exc:
            raise RigBusy(f"{self.resource}: its lock file {self.path} cannot be made "
                          f"({exc.strerror}): point {LOCK_DIR_ENV} at a writable "
                          "directory") from None
        return os.fdopen(fd, "r+", encoding="utf-8"), True

    def _busy_message(self) -> str:
        info = holder(self.path)
        rig = f" (rig {info['rig_id']!r})" if info.get("rig_id") else ""
        return (f"{self.resource} is in use by another pamd daemon{rig}: "
                f"{describe_holder(info)}; nothing was opened or moved. Stop it first: "
                "`systemctl stop pamd` for the service, Ctrl-C (or `kill "
                f"{info.get('pid', '<pid>')}`) for a `pamd run`, `pamd collect`, `pamd "
                f"tune` or `pamd emulate` in a terminal; then try again (lock: {self.path})")


class RunLocks:
    """The locks of one run: one per resource it opens (`resources`, e.g. the drivers'
    claims and the state directory), taken together in a fixed order (so two daemons
    that want the same two never hold one each) or not at all."""

    def __init__(self, resources: Sequence[str], rig_id: str,
                 directory: str | None = None) -> None:
        self.rig_id = rig_id
        self.locks = [ResourceLock(r, rig_id, directory) for r in sorted(set(resources))]

    @property
    def held(self) -> bool:
        """Every lock of the run is held (and it has at least one)."""
        return bool(self.locks) and all(lk.held for lk in self.locks)

    @property
    def resources(self) -> list[str]:
        return [lk.resource for lk in self.locks]

    @property
    def paths(self) -> list[str]:
        return [lk.path for lk in self.locks]

    def acquire(self, what: str = "") -> None:
        """Take every lock, or none (RigBusy naming the first that is held)."""
        try:
            for lk in self.locks:
                lk.acquire(what)
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        for lk in reversed(self.locks):
            lk.release()

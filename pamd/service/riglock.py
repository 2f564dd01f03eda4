"""One daemon per rig: an exclusive, non-blocking `flock` on a lock file named for the
rig (`pamd-<rig_id>.lock`), taken before anything opens and held for the daemon's
life. The kernel releases it when the process ends, however it ends (SIGKILL, a
crash): there is never a stale lock to clean up. A second daemon on the same rig
(`pamd run`, `pamd tune`, a collection) is refused with who holds it: the holder
writes its pid, command line and start time into the file.

Where the lock files are (the first that applies):

1. `PAMD_LOCK_DIR` (tests give each test its own; a lab with its own convention);
2. `RUNTIME_DIRECTORY` (systemd sets it: `RuntimeDirectory=pamd`, i.e. /run/pamd);
3. /run/pamd when it exists (made at boot by systemd/pamd.tmpfiles.conf, mode 1777):
   so a `pamd run` started by hand and the service see each other's lock;
4. `$XDG_RUNTIME_DIR/pamd`, else `<tmp>/pamd-<uid>` (no service installed).

A lock file the daemon cannot write (another user's, in /run/pamd) is still locked,
opened read-only: the lock is what matters, the holder's note is a courtesy.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import re
import sys
import tempfile
import time
from typing import IO

from pamd.errors import PamdError

LOCK_DIR_ENV = "PAMD_LOCK_DIR"
SYSTEM_LOCK_DIR = "/run/pamd"


class RigBusy(PamdError):
    """Another daemon holds the rig: nothing was opened."""

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


def lock_path(rig_id: str, directory: str | None = None) -> str:
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", rig_id) or "rig"
    return os.path.join(directory or lock_dir(), f"pamd-{safe}.lock")


def holder(path: str) -> dict[str, object]:
    """What the holder wrote into the lock file ({} if nothing readable)."""
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.loads(fh.read() or "{}")
    except (OSError, ValueError):
        return {}
    return doc if isinstance(doc, dict) else {}


def describe_holder(info: dict[str, object]) -> str:
    pid = info.get("pid", "?")
    cmd = info.get("command") or "an unknown command"
    since = info.get("since") or "an unknown time"
    return f"pid {pid} ({cmd}), since {since}"


class RigLock:
    """The lock of one rig. `acquire()` (RigBusy if held), `release()`."""

    def __init__(self, rig_id: str, directory: str | None = None) -> None:
        self.rig_id = rig_id
        self.path = lock_path(rig_id, directory)
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
            note = {"pid": os.getpid(), "command": what or " ".join(sys.argv),
                    "since": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "rig_id": self.rig_id}
            with contextlib.suppress(OSError):
                fh.seek(0)
                fh.truncate()
                fh.write(json.dumps(note) + "\n")
                fh.flush()
        self._fh = fh

    def release(self) -> None:
        """Let the rig go (closing the file releases the lock; the file stays)."""
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
                raise RigBusy(f"rig {self.rig_id!r}: its lock file {self.path} cannot be "
                              f"opened ({exc.strerror}): let this user write {directory} "
                              f"or point {LOCK_DIR_ENV} at a directory it can") from None
        except OSError as exc:
            raise RigBusy(f"rig {self.rig_id!r}: its lock file {self.path} cannot be made "
                          f"({exc.strerror}): point {LOCK_DIR_ENV} at a writable "
                          "directory") from None
        return os.fdopen(fd, "r+", encoding="utf-8"), True

    def _busy_message(self) -> str:
        info = holder(self.path)
        return (f"rig {self.rig_id!r} is in use by another pamd daemon: "
                f"{describe_holder(info)}; nothing was opened or moved. Stop it first: "
                "`systemctl stop pamd` for the service, Ctrl-C (or `kill "
                f"{info.get('pid', '<pid>')}`) for a `pamd run`, `pamd collect` or "
                f"`pamd tune` in a terminal; then try again (lock: {self.path})")

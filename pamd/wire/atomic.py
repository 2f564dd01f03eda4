"""The one way pamd writes a file it keeps: whole, or not at all (issue 37 item 3).

Configs on `--save` (`pamd tune`, `pamd commission`), the home/tare datums, the
latched fault and the safe outputs, a collection's manifest, model files, the command
credential, the service's unit files, exports and plots: each is written to a
temporary file in the same directory (created exclusively, so two writers never share
one), flushed and fsynced, then renamed over the old file, and the directory fsynced
so that the rename survives a power cut. Until the rename the old file is untouched;
after it the new one is there whole. A failure on the way (a full disk, a file-size
limit, a read-only directory, no permission) removes the temporary file, leaves the old
file exactly as it was, and raises `FileWriteError` naming the file and saying that.

Before, `pamd commission --save` under a 3 KiB file-size limit (standing in for a full
disk) cut the config to 3072 bytes, its `control:` and `safety:` sections gone, and
`pamd check-config` called it valid: the next start ran on default gains.

The file that is replaced keeps its permissions (and its owner, where pamd may set
it); one written through a symlink replaces the link's target, not the link. Streams
written as they are made (MCAP recordings: `pamd.wire.record`, which has its own crash
recovery) and lock files are not written here.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from typing import BinaryIO, Protocol, TextIO

from pamd.wire.errors import FileWriteError

#: a new file's permissions before the umask (as `open()` makes them)
NEW_FILE_MODE = 0o666


def fsync_dir(directory: str) -> None:
    """Make a rename or an unlink in `directory` durable (best effort: some file
    systems cannot fsync a directory)."""
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _target(path: str | os.PathLike[str]) -> str:
    """The file a write to `path` replaces: a symlink's target (the link stays)."""
    return os.path.realpath(os.fspath(path))


def _temporary(target: str, file_mode: int | None) -> tuple[str, int, os.stat_result | None]:
    """A new temporary file beside `target` (name, descriptor, the old file's stat)."""
    directory = os.path.dirname(target)
    try:
        old: os.stat_result | None = os.stat(target)
    except FileNotFoundError:
        old = None
    mode = (old.st_mode & 0o7777 if old is not None and file_mode is None
            else NEW_FILE_MODE if file_mode is None else file_mode)
    tmp = os.path.join(directory, f".{os.path.basename(target)}.{uuid.uuid4().hex[:12]}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, mode)
    if file_mode is not None or old is not None:
        with contextlib.suppress(OSError):
            os.fchmod(fd, mode)  # the old file's (or the one asked for), whatever the umask
    if old is not None and file_mode is None:
        with contextlib.suppress(OSError):
            os.fchown(fd, old.st_uid, old.st_gid)  # where pamd may (root, or its own)
    return tmp, fd, old


def _failed(path: str, exc: OSError, existed: bool) -> FileWriteError:
    why = exc.strerror or str(exc)
    kept = (f"{path} is as it was" if existed else f"no {os.path.basename(path)} was written")
    return FileWriteError(f"cannot write {path}: {why}; {kept} (free space, permissions "
                          "or a file-size limit?)")


@contextlib.contextmanager
def _replacing(path: str | os.PathLike[str], durable: bool, file_mode: int | None,
               exclusive: bool) -> Iterator[int]:
    """A temporary file's descriptor beside `path` (the caller writes, syncs and closes
    it); on leaving without an exception it replaces `path` (or, `exclusive`, is linked
    there); on any failure it is removed and `path` is untouched."""
    target = _target(path)
    try:
        tmp, fd, old = _temporary(target, file_mode)
    except OSError as exc:
        raise _failed(target, exc, os.path.exists(target)) from exc
    try:
        yield fd
        if exclusive:
            os.link(tmp, target)  # fails if a file appeared meanwhile
        else:
            os.replace(tmp, target)
    except FileExistsError:
        raise
    except OSError as exc:
        raise _failed(target, exc, old is not None) from exc
    finally:
        with contextlib.suppress(OSError):
            os.close(fd)  # closed by its file object already, but for a failed open
        with contextlib.suppress(OSError):
            os.unlink(tmp)  # gone after a rename; after a link or a failure: removed
    if durable:
        fsync_dir(os.path.dirname(target))


@contextlib.contextmanager
def atomic_text(path: str | os.PathLike[str], *, durable: bool = True,
                file_mode: int | None = None, exclusive: bool = False,
                newline: str | None = None) -> Iterator[TextIO]:
    """A text file (UTF-8) to write `path` through: leaving the block without an
    exception replaces `path` whole; with one (or a failed write: FileWriteError naming
    the file), `path` is untouched.

    `durable`: fsync the file and the directory (False: a crash of the process cannot
    leave half a file, a power cut may lose the new one: what a reply with a deadline
    affords). `file_mode`: a new file's permissions (default: as `open()` makes them;
    a file replaced keeps its own). `exclusive`: never replace a file that is there
    (FileExistsError, not wrapped: the caller decides)."""
    with _replacing(path, durable, file_mode, exclusive) as fd, \
            os.fdopen(fd, "w", encoding="utf-8", newline=newline, closefd=False) as fh:
        yield fh
        fh.flush()
        if durable:
            os.fsync(fd)


@contextlib.contextmanager
def atomic_binary(path: str | os.PathLike[str], *, durable: bool = True,
                  file_mode: int | None = None, exclusive: bool = False) -> Iterator[BinaryIO]:
    """`atomic_text` for bytes (a plot, a model's binary form)."""
    with _replacing(path, durable, file_mode, exclusive) as fd, \
            os.fdopen(fd, "wb", closefd=False) as fh:
        yield fh
        fh.flush()
        if durable:
            os.fsync(fd)


def write_atomic(path: str | os.PathLike[str], data: str | bytes, *, durable: bool = True,
                 file_mode: int | None = None, exclusive: bool = False) -> None:
    """Write `data` (text as UTF-8, or bytes) to `path` whole or not at all
    (`atomic_text`); FileWriteError naming the file if it cannot be written."""
    if isinstance(data, bytes):
        with atomic_binary(path, durable=durable, file_mode=file_mode,
                           exclusive=exclusive) as fb:
            fb.write(data)
    else:
        with atomic_text(path, durable=durable, file_mode=file_mode,
                         exclusive=exclusive) as ft:
            ft.write(data)


class Figure(Protocol):
    """What `save_figure` needs of a plot (a matplotlib Figure)."""

    def savefig(self, fname: BinaryIO, *, format: str, dpi: float) -> None: ...


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: float) -> None:
    """A plot written whole or not at all, in the format its file name says (.png,
    .svg, .pdf; png without a suffix)."""
    fmt = os.path.splitext(os.fspath(path))[1][1:].lower() or "png"
    with atomic_binary(path) as fh:
        fig.savefig(fh, format=fmt, dpi=dpi)

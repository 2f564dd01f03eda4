"""Files a remote command names (a `collect`'s plan, a `model`'s model file): only by
name, only from the directory the config allows (`telemetry.plans_dir`,
`telemetry.models_dir`), with a size, a nesting and a time limit: a plan at most 1 MiB,
a model 8 MiB (`pamd.config.schema.MODEL_FILE_MAX_BYTES`, declared with the config keys
that name these directories: the one cap every reader of model files applies), nested at most 64
deep, read and parsed within `PARSE_TIME_LIMIT_S` in a child process
(`pamd.loop.commands.offload`), so within a client's default 5 s command timeout.

Every refusal names the file and, where it applies, the line and column; none ever
quotes the file's contents (a request may name any file the daemon could read, and
its refusal is answered, published on the events key and recorded).

Nesting is measured by one pass over the text (brackets and braces outside quoted
strings) before any parser sees it, so a 100,000-deep file is refused with its
position instead of ending in a RecursionError.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.config.schema import PLAN_FILE_MAX_BYTES
from pamd.models.registry import MAX_FILE_BYTES
from pamd.wire.errors import CommandRefused

MAX_DEPTH = 64
PLAN_MAX_BYTES = PLAN_FILE_MAX_BYTES
MODEL_MAX_BYTES = MAX_FILE_BYTES
#: A file a command names is read, parsed and checked within this (seconds), or refused.
PARSE_TIME_LIMIT_S = 3.0
#: ... and within this share of `telemetry.command_timeout_s`, where that is shorter.
PARSE_TIMEOUT_SHARE = 0.6


def parse_time_limit_s(cfg: LoadedConfig) -> float:
    """How long a command's file may take to read: PARSE_TIME_LIMIT_S, or less where
    the config's command timeout would not leave the rest of the way its time."""
    return min(PARSE_TIME_LIMIT_S,
               PARSE_TIMEOUT_SHARE * cfg.rig.telemetry.command_timeout_s)
_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.+-]{0,127}$")


@dataclass(frozen=True)
class NamedFile:
    """A file read within the limits: where it is, what it is called, its text."""

    path: str
    name: str
    text: str


def resolve(name: str, directory: str | None, what: str, key: str) -> str:
    """The path of file `name` in `directory` (the config's `telemetry.<key>`, already
    absolute); CommandRefused unless `name` is a plain file name there."""
    if directory is None:
        raise CommandRefused(f"remote {what} files are off on this daemon: set "
                             f"telemetry.{key} in its config to the directory they may "
                             "come from")
    if not isinstance(name, str) or not _NAME_RE.match(name) or name.endswith("."):
        raise CommandRefused(f"{what} file {_shown(name)} must be a file name in "
                             f"telemetry.{key} (letters, digits, '_', '-', '.', '+'; no "
                             "directories)")
    base = os.path.realpath(directory)
    path = os.path.realpath(os.path.join(base, name))
    if os.path.dirname(path) != base:  # a symlink leading out of the directory
        raise CommandRefused(f"{what} file {name!r} is not in telemetry.{key}")
    return path


def read_limited(path: str, name: str, what: str, max_bytes: int) -> NamedFile:
    """The file's UTF-8 text, at most `max_bytes`, nested at most MAX_DEPTH deep."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | os.O_NONBLOCK)
    except OSError as exc:
        raise CommandRefused(f"{what} file {name!r}: {exc.strerror or 'cannot be opened'}"
                             ) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise CommandRefused(f"{what} file {name!r} is not a regular file")
        if st.st_size > max_bytes:
            raise CommandRefused(f"{what} file {name!r} is {st.st_size} bytes, above the "
                                 f"limit of {max_bytes} bytes")
        chunks, got = [], 0
        while got <= max_bytes:
            b = os.read(fd, min(1 << 20, max_bytes + 1 - got))
            if not b:
                break
            chunks.append(b)
            got += len(b)
    except OSError as exc:
        raise CommandRefused(f"{what} file {name!r}: {exc.strerror or 'cannot be read'}"
                             ) from None
    finally:
        os.close(fd)
    data = b"".join(chunks)
    if len(data) > max_bytes:
        raise CommandRefused(f"{what} file {name!r} is more than {max_bytes} bytes (the "
                             "limit)")
    text = decode(data, name, what)
    check_nesting(text, name, what)
    return NamedFile(path, name, text)


def decode(data: bytes, name: str, what: str) -> str:
    """Strict UTF-8; the refusal says where the first bad byte is."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _position(data, exc.start)
        raise CommandRefused(f"{what} file {name!r} is not UTF-8 text (byte {exc.start}, "
                             f"line {line}, column {col})") from None


def check_nesting(text: str, name: str, what: str, max_depth: int = MAX_DEPTH) -> None:
    """Refuse brackets/braces nested deeper than `max_depth` (outside quoted strings)."""
    depth = 0
    quote = ""
    escaped = False
    line, line_start = 1, 0
    for i, ch in enumerate(text):
        if ch == "\n":
            line, line_start = line + 1, i + 1
        if quote:
            if escaped:
                escaped = False
            elif ch == "\\" and quote == '"':
                escaped = True
            elif ch == quote or (ch == "\n" and quote == "#"):
                quote = ""
            continue
        if ch in "[{":
            depth += 1
            if depth > max_depth:
                raise CommandRefused(f"{what} file {name!r}: nested more than {max_depth} "
                                     f"levels deep at line {line}, column {i - line_start + 1}")
        elif ch in "]}":
            depth = max(0, depth - 1)
        elif ch == '"' or (ch == "'" and not _in_word(text, i)):
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1] in " \t\n"):
            quote = "#"  # a YAML comment, to its line's end


def _in_word(text: str, i: int) -> bool:
    """An apostrophe inside a plain YAML scalar (it's) opens no string."""
    return i > 0 and (text[i - 1].isalnum())


def _position(data: bytes, offset: int) -> tuple[int, int]:
    line = data.count(b"\n", 0, offset) + 1
    return line, offset - (data.rfind(b"\n", 0, offset) + 1) + 1


def _shown(value: object) -> str:
    """A name for a refusal, never more than 80 characters of it."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def configured_dir(cfg: LoadedConfig, key: str) -> str | None:
    """`telemetry.<key>` of a loaded config, absolute (relative to the config file)."""
    rel: str | None = getattr(cfg.rig.telemetry, key, None)  # plans_dir, models_dir
    if not rel:
        return None
    base = os.path.dirname(os.path.abspath(cfg.path))
    return os.path.join(base, os.path.expanduser(rel))


def issues_text(exc: Exception, name: str) -> str:
    """A ConfigError's issues with the file's name, line, key and what was expected,
    never what was found there (that is the file's contents)."""
    issues = getattr(exc, "issues", None)
    if not issues:
        return f"{name}: {exc.__class__.__name__}"
    parts = []
    for i in issues[:5]:
        where = f"{name}:{i.line}" if i.line else name
        path = str(i.path or "")
        key = (f" {path}:" if _KEY_PATH_RE.match(path) else " (a key of the file's own):"
               ) if path else ""
        found = f", found {i.found}" if _NUMBER_RE.match(str(i.found or "")) else ""
        parts.append(f"{where}:{key} expected {_cap(i.expected, 160)}{found}")
    more = f" (and {len(issues) - 5} more)" if len(issues) > 5 else ""
    return "; ".join(parts) + more


_NUMBER_RE = re.compile(r"^[-+]?[0-9][0-9.eE+-]{0,24}$")
_KEY_PATH_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,40}(\[\d+\])?"
                          r"(\.[A-Za-z_][A-Za-z0-9_]{0,40}(\[\d+\])?){0,5}$")


def _cap(text: str, n: int) -> str:
    text = str(text)
    return text if len(text) <= n else text[:n - 3] + "..."

"""The command credential: a random token the daemon writes into a file readable by
its user and group only (mode 0640, as Jupyter's token or Docker's socket group), which
every command must carry (a Zenoh query's attachment), on loopback too. Status and
telemetry stay open, read-only; an `estop` is honoured without it (anyone who can reach
the daemon may stop the rig) and recorded as such. On a lab network the router's mutual
TLS and access-control roles still decide who reaches the daemon at all.

Where the token file is, `pamd-<rig_id>.token` in the first of:

1. `PAMD_TOKEN_DIR` (a lab's own place; the tests give each run its own);
2. `RUNTIME_DIRECTORY` (systemd: /run/pamd for the service; a user in the service's
   group reads it there);
3. `$XDG_RUNTIME_DIR/pamd` (a login session's private directory);
4. `<tmp>/pamd-<uid>` (mode 0700; refused if another user owns it).

The daemon keeps a token it finds there (readable, its own, a token's shape) and
makes one otherwise, atomically (a file appears whole or not at all), so daemons of
the same rig started one after another by one user share it. The client (`pamd cmd`,
`pamd.connect`) uses, in order: `--token-file` / `token_file=`, `PAMD_TOKEN_FILE`,
`PAMD_TOKEN` (the token itself), then `pamd-<rig_id>.token` in the directories above
and /run/pamd. Only the token's SHA-256 goes to the io process, which compares hashes
in constant time (`hmac.compare_digest`).
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import os
import re
import secrets
import stat
import tempfile

from pamd.errors import PamdError

TOKEN_DIR_ENV = "PAMD_TOKEN_DIR"
TOKEN_FILE_ENV = "PAMD_TOKEN_FILE"
TOKEN_ENV = "PAMD_TOKEN"
SERVICE_DIR = "/run/pamd"
TOKEN_RE = re.compile(r"^[A-Za-z0-9_-]{32,128}$")
FILE_MODE = 0o640
MAX_TOKEN_BYTES = 256
ATTACHMENT_PREFIX = b"pamd-token:"


class CredentialError(PamdError):
    """No token could be written or read where it should be."""

    exit_code = 2


def token_dirs() -> list[str]:
    """Where a daemon writes its token, in order of preference (module docstring)."""
    out = []
    for env in (TOKEN_DIR_ENV, "RUNTIME_DIRECTORY"):
        value = os.environ.get(env)
        if value:
            out.append(value.split(":")[0])
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg and os.path.isdir(xdg):
        out.append(os.path.join(xdg, "pamd"))
    out.append(os.path.join(tempfile.gettempdir(), f"pamd-{os.getuid()}"))
    return out


def file_name(rig_id: str) -> str:
    return f"pamd-{re.sub(r'[^A-Za-z0-9_.-]', '_', rig_id) or 'rig'}.token"


def digest(token: str | bytes) -> str:
    """The SHA-256 (hex) of a token, as the io process keeps it."""
    raw = token.encode("utf-8", "replace") if isinstance(token, str) else token
    return hashlib.sha256(raw).hexdigest()


def matches(presented: bytes | None, expected_sha256: str) -> bool:
    """Whether a query's attachment carries the token whose hash is expected (constant
    time in the token's content)."""
    if not presented or not presented.startswith(ATTACHMENT_PREFIX):
        return False
    token = presented[len(ATTACHMENT_PREFIX):len(ATTACHMENT_PREFIX) + MAX_TOKEN_BYTES]
    return hmac.compare_digest(digest(token), expected_sha256)


def attachment(token: str) -> bytes:
    return ATTACHMENT_PREFIX + token.encode("ascii", "replace")


def _private_dir(path: str) -> bool:
    """`path` exists or was made (mode 0700 when made), and is ours or root's and not
    writable by others (a directory someone else controls could hand us their file)."""
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
        st = os.stat(path)
    except OSError:
        return False
    if not stat.S_ISDIR(st.st_mode) or st.st_uid not in (os.getuid(), 0):
        return False
    return not (st.st_mode & 0o002) or bool(st.st_mode & stat.S_ISVTX)


def _read(path: str, own: bool) -> str | None:
    """The token in `path` if it is one (and, `own`, the file is ours and not readable
    by others), else None."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_TOKEN_BYTES:
            return None
        if own and (st.st_uid != os.getuid() or st.st_mode & 0o007):
            return None
        text = os.read(fd, MAX_TOKEN_BYTES).decode("ascii", "replace").strip()
    finally:
        os.close(fd)
    return text if TOKEN_RE.match(text) else None


def _write_new(path: str) -> str | None:
    """A new token written whole under `path` (never over another's); the token that is
    there afterwards (ours, or a concurrent daemon's), or None."""
    # Imported here: the io process imports this module to check tokens (its budget of
    # pamd modules), only the daemon's main process writes one.
    from pamd.atomic import write_atomic

    token = secrets.token_urlsafe(32)
    try:  # whole, never over another's (`pamd.atomic`)
        write_atomic(path, token + "\n", file_mode=FILE_MODE, exclusive=True)
    except FileExistsError:  # a token appeared meanwhile: that one wins
        return _read(path, own=True)
    except OSError:
        return None
    return token


def ensure_token(rig_id: str) -> tuple[str, str]:
    """The daemon's side: (token file, SHA-256 of its token), the token kept or made
    in the first directory where that works; CredentialError if none does."""
    tried = []
    for d in token_dirs():
        path = os.path.join(d, file_name(rig_id))
        if not _private_dir(d):
            tried.append(f"{d} (not a directory of this user's)")
            continue
        token = _read(path, own=True)
        if token is None and os.path.lexists(path):
            with contextlib.suppress(OSError):  # not a token of ours: replace it
                os.unlink(path)
        if token is None:
            token = _write_new(path)
        if token is not None:
            return path, digest(token)
        tried.append(f"{path} (cannot write)")
    raise CredentialError(f"cannot keep the command token of rig {rig_id!r}: tried "
                          f"{'; '.join(tried)}; set {TOKEN_DIR_ENV} to a directory of "
                          "this user's")


def find_token(rig_id: str, token_file: str | None = None) -> tuple[str | None, str]:
    """The client's side: (token or None, where it came from or where it was looked
    for), from `token_file`, the environment, or the token directories."""
    file = token_file or os.environ.get(TOKEN_FILE_ENV)
    if file:
        tok = _read(os.path.expanduser(file), own=False)
        return tok, file if tok else f"{file} (no token there, or not readable)"
    env = os.environ.get(TOKEN_ENV)
    if env:
        tok = env.strip()
        return (tok, f"${TOKEN_ENV}") if TOKEN_RE.match(tok) else (
            None, f"${TOKEN_ENV} (not a token)")
    looked = []
    for d in [*token_dirs(), SERVICE_DIR]:
        path = os.path.join(d, file_name(rig_id))
        if path in looked:
            continue
        looked.append(path)
        tok = _read(path, own=False)
        if tok is not None:
            return tok, path
    return None, ", ".join(looked)

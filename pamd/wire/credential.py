"""The command credential: a random token the daemon writes into a file readable by
its user and group only (mode 0640, as Jupyter's token or Docker's socket group), with
which every command is signed, on loopback too. Status and telemetry stay open,
read-only; an `estop` is honoured without it (anyone who can reach the daemon may stop
the rig) and recorded as such. On a lab network the router's mutual TLS and
access-control roles still decide who reaches the daemon at all.

The token never travels. Each command carries in its attachment a MAC (HMAC-SHA256,
keyed by the token's SHA-256) over the rig, the verb, the payload, the client's id, a
counter and the daemon's run nonce (`Signer`; `pamd-mac1 <client> <counter> <nonce>
<mac>`). The io process checks it (`Verifier`, constant time) and takes each client's
counters strictly increasing, so a captured command cannot be sent again: not in this
run (its counter is spent), nor to a later daemon (its nonce, the `command_nonce` the
status says, is new each run). The counter is the client's clock in ns (or one more
than its last), so a client the daemon has forgotten (it keeps the newest
`MAX_CLIENTS`) starts above every counter it forgot. The token's old clear form
(`pamd-token:`) is refused, saying so.

Rotating the token needs no deletion: `pamd token --rotate` writes a new one over the
old atomically (`rotate_token`), and a running daemon's io process takes it within a
second (`TokenWatch`); commands signed with the old one are refused from then on.

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
and /run/pamd. Only the token's SHA-256 goes to the io process (the MAC's key).
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import math
import os
import re
import secrets
import stat
import tempfile
import time
from collections import OrderedDict

from pamd.wire.errors import PamdError

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


# -- a MAC per command ---------------------------------------------------------------
MAC_PREFIX = "pamd-mac1"
#: the payload's bytes the MAC covers (with its length): an estop or stop acts whatever
#: its size, and checking it costs at most this much hashing
MAC_PAYLOAD_BYTES = 64 * 1024
#: clients whose last counter the io process keeps (the newest; a counter at or below
#: the highest of those it forgot is refused)
MAX_CLIENTS = 4096
MAX_ATTACHMENT_BYTES = 256
_ID_RE = re.compile(r"^[0-9a-f]{8,32}$")


def mac_key(token_sha256: str) -> bytes:
    """The MAC's key: the token's SHA-256 (what the io process holds)."""
    return bytes.fromhex(token_sha256)


def _mac(key: bytes, rig: str, verb: str, client: str, counter: int, nonce: str,
         payload: bytes) -> str:
    head = f"{rig}\n{verb}\n{client}\n{counter}\n{nonce}\n{len(payload)}\n".encode()
    return hmac.new(key, head + payload[:MAC_PAYLOAD_BYTES], hashlib.sha256).hexdigest()


class Signer:
    """A client's side: signs each command (`attachment`) with a counter of its own."""

    def __init__(self, token: str) -> None:
        self.key = mac_key(digest(token))
        self.client = secrets.token_hex(8)
        self.last = 0

    def attachment(self, rig: str, verb: str, payload: bytes, nonce: str) -> bytes:
        counter = max(self.last + 1, time.time_ns())
        self.last = counter
        mac = _mac(self.key, rig, verb, self.client, counter, nonce, payload)
        return f"{MAC_PREFIX} {self.client} {counter} {nonce} {mac}".encode()


#: why a command's credential was not taken (Verifier.check), for its refusal
NONE, CLEAR, STALE, BAD, REPLAY = "none", "clear", "stale", "bad", "replay"


class Verifier:
    """The io process's side: a command's MAC checked against the token's hash
    (`set_key` on a rotation), its counter against the client's last."""

    def __init__(self, token_sha256: str, nonce: str) -> None:
        self.key = mac_key(token_sha256) if token_sha256 else b""
        self.nonce = nonce
        self.last: OrderedDict[str, int] = OrderedDict()
        self.floor = 0  # the highest counter of the clients forgotten

    def set_key(self, token_sha256: str) -> None:
        self.key = mac_key(token_sha256)

    def check(self, presented: bytes | None, rig: str, verb: str, payload: bytes) -> str | None:
        """None if the attachment signs this command, new; else why not (NONE, CLEAR:
        the old clear token, STALE: another run's nonce, BAD, REPLAY)."""
        if not presented:
            return NONE
        if presented.startswith(ATTACHMENT_PREFIX):
            return CLEAR
        parts = presented[:MAX_ATTACHMENT_BYTES].decode("ascii", "replace").split(" ")
        if len(parts) != 5 or parts[0] != MAC_PREFIX or not _ID_RE.match(parts[1]) \
                or not parts[2].isdigit() or len(parts[2]) > 20:
            return BAD
        _, client, count, nonce, mac = parts
        if nonce != self.nonce:
            return STALE
        counter = int(count)
        want = _mac(self.key, rig, verb, client, counter, nonce, payload)
        if not hmac.compare_digest(want, mac):
            return BAD
        last = self.last.get(client, self.floor)
        if counter <= last:
            return REPLAY
        self.last[client] = counter
        self.last.move_to_end(client)
        while len(self.last) > MAX_CLIENTS:
            self.floor = max(self.floor, self.last.popitem(last=False)[1])
        return None


class TokenWatch:
    """The io process follows its token file: a rotated token (a new file in its
    place) is read at most every `period_s` (`changed` gives its hash once)."""

    def __init__(self, path: str, period_s: float = 1.0) -> None:
        self.path = path
        self.period_s = period_s
        self.t = -math.inf
        self.seen = self._id()

    def _id(self) -> tuple[int, int, int] | None:
        try:
            st = os.stat(self.path)
        except OSError:
            return None
        return st.st_ino, st.st_mtime_ns, st.st_size

    def changed(self, now: float) -> str | None:
        """The new token's SHA-256 if the file changed since it was last read."""
        if not self.path or now - self.t < self.period_s:
            return None
        self.t = now
        seen = self._id()
        if seen is None or seen == self.seen:
            return None
        token = _read(self.path, own=True)
        if token is None:
            return None  # half-written or not ours: the old one stays, looked at again
        self.seen = seen
        return digest(token)


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


def _write_new(path: str, replace: bool = False) -> str | None:
    """A new token written whole under `path`: never over another's (a concurrent
    daemon's wins), or, `replace`, in place of the old one atomically (a rotation:
    readers see the old file or the new, never half). The token that is there
    afterwards, or None."""
    # Imported here: the io process imports this module to check tokens (its budget of
    # pamd modules), only the daemon's main process and `pamd token` write one.
    from pamd.wire.atomic import write_atomic

    token = secrets.token_urlsafe(32)
    try:  # whole (`pamd.wire.atomic`); a first token never over another's
        write_atomic(path, token + "\n", file_mode=FILE_MODE, exclusive=not replace)
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


def rotate_token(rig_id: str, token_file: str | None = None) -> str:
    """A new token in place of the rig's (its file as `find_token` finds it, or
    `token_file`), written atomically over the old one: nothing to delete, and a running
    daemon takes it within a second. The file's path; CredentialError if there is none
    of this user's to replace."""
    tok, where = find_token(rig_id, token_file)
    path = token_file or (where if tok is not None and os.path.isfile(where) else None)
    if path is None:
        raise CredentialError(f"no command token of rig {rig_id!r} to rotate (looked in "
                              f"{where}); a daemon makes one as it starts")
    path = os.path.expanduser(path)
    if _read(path, own=True) is None:
        raise CredentialError(f"{path} is not a token file of this user's (mode 0640, "
                              "owned by the daemon's user): rotate it as that user")
    if _write_new(path, replace=True) is None:
        raise CredentialError(f"cannot write a new token into {os.path.dirname(path)}")
    return path

"""The local channel: a Unix socket the io process serves beside the command token
(`pamd-<rig>.<pid>.sock` in the token's directory, mode 0660: the daemon's user and group,
who may read the token anyway), outside Zenoh. On the rig PC `pamd status` and `pamd
cmd` (an estop above all) go this way, so no number of Zenoh sessions can keep them
out: 100 sessions without a credential on the daemon's endpoint (its cap) had locked
everyone out, the remote estop included.

Who may use it is the kernel's to say: connecting needs write access to the socket
file, in a directory only the daemon's user (and, for the service, its group) may
enter; the peer's uid and pid (SO_PEERCRED) name the sender in the record. A command
that comes this way needs no signature (`CommandIntake.on_command(trusted=True)`); it
passes every other check a Zenoh command passes (rate, ranges, the loop's verdict).

The server is one thread of the io process (`LocalServer`), blocked in `select` when
idle, at most MAX_CONNECTIONS connections (more are closed at once), each request
bounded. Requests: one JSON header line (`op`: hello, status or cmd; `verb`, `user`,
`n`: the payload's bytes), then the payload; each answer is one JSON line. `hello`
says the rig, the daemon's pid and where its Zenoh session listens, so a client that
names an endpoint (`--connect`) uses the local channel of the daemon listening there
only. The client is `LocalClient`; `socket_paths` finds a rig's sockets
(`pamd.client.remote.local_rig` chooses).

Each daemon has its own socket (`pamd-<rig>.<pid>.sock`): a client that names no
endpoint takes the rig's one daemon on this machine (several: it names none, and Zenoh
decides). A daemon removes the sockets of its rig nobody answers on (a killed
daemon's) as it opens its own, and its io process removes its own as it closes.
"""

from __future__ import annotations

import contextlib
import json
import os
import pwd
import select
import socket
import struct
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from pamd.wire.credential import SERVICE_DIR, file_name, token_dirs
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.zconf import NoDaemon

SOCKET_MODE = 0o660
MAX_CONNECTIONS = 16
MAX_HEADER_BYTES = 4096
MAX_BODY_BYTES = 1 << 20  # an estop's or stop's payload is cut by the client first
IDLE_S = 30.0  # a connection with nothing asked for this long is closed
MAX_PATH_BYTES = 107  # sun_path, less its terminating NUL
_UCRED = struct.Struct("3i")  # pid, uid, gid

if TYPE_CHECKING:  # a port: a type only (the node's seams)
    from pamd.wire.seams import Query

Handler = Callable[["Query"], None]


def _prefix(rig_id: str) -> str:
    return file_name(rig_id).removesuffix(".token") + "."


def socket_path(token_file: str, rig_id: str, pid: int) -> str:
    """The local channel's path: beside the token, `pamd-<rig>.<daemon's pid>.sock` (each
    daemon its own, so two daemons of a rig on one machine both have one)."""
    return os.path.join(os.path.dirname(token_file), f"{_prefix(rig_id)}{pid}.sock")


def _rig_sockets(directory: str, rig_id: str | None) -> list[str]:
    """The sockets of `rig_id`'s daemons (None: of every rig) in `directory`."""
    try:
        names = sorted(os.listdir(directory))
    except OSError:
        return []
    out = []
    for name in names:
        stem = name.removesuffix(".sock")
        if stem == name or not name.startswith("pamd-"):
            continue
        rig_part, _, pid = stem.rpartition(".")
        if pid.isdigit() and (rig_id is None or rig_part + "." == _prefix(rig_id)):
            out.append(os.path.join(directory, name))
    return out


def clear_stale(directory: str, rig_id: str) -> int:
    """Remove the sockets of `rig_id`'s daemons that nobody answers on any more (a
    daemon killed with its io process); how many."""
    n = 0
    for path in _rig_sockets(directory, rig_id):
        if _owner(path) is None:
            with contextlib.suppress(OSError):
                os.unlink(path)
                n += 1
    return n


# -- the server (the io process) --------------------------------------------------------
class _Bytes:
    def __init__(self, b: bytes) -> None:
        self.b = b

    def to_bytes(self) -> bytes:
        return self.b


class _Parameters:
    def __init__(self, user: str) -> None:
        self.user = user

    def get(self, key: str, default: str | None = None) -> str | None:
        return self.user if key == "user" and self.user else default


class LocalQuery:
    """A request from the local channel in the shape of a Zenoh query (`pamd.wire.seams.
    Query`): what the status answer and the command intake read, and their reply."""

    attachment = None  # the kernel named the peer: no signature needed
    source_info = None

    def __init__(self, conn: _Conn, key: str, payload: bytes, user: str) -> None:
        self.conn = conn
        self.key_expr = key
        self.payload = _Bytes(payload)
        self.parameters = _Parameters(user)

    def reply(self, key_expr: str, payload: bytes, *, encoding: str | None = None) -> None:
        self.conn.send(payload + b"\n")

    def drop(self) -> None:
        pass


class _Conn:
    def __init__(self, sock: socket.socket, sender: str) -> None:
        self.sock = sock
        self.sender = sender
        self.buf = b""
        self.t = time.monotonic()
        self.lock = threading.Lock()
        self.dead = False
        self.ending = False  # refused: what comes is read and dropped until the peer closes

    def send(self, data: bytes) -> None:
        """From any thread, never blocking: a peer that does not read its answers loses
        its connection."""
        with self.lock:
            if self.dead:
                return
            try:
                sent = self.sock.send(data, socket.MSG_DONTWAIT)
            except OSError:
                sent = -1
            if sent != len(data):
                self.dead = True
                with contextlib.suppress(OSError):
                    self.sock.shutdown(socket.SHUT_RDWR)


def peer_name(sock: socket.socket) -> str:
    """`local:<user> pid <pid>`, as the kernel says (SO_PEERCRED)."""
    try:
        pid, uid, _gid = _UCRED.unpack(sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED,
                                                       _UCRED.size))
    except OSError:
        return "local"
    try:
        user = pwd.getpwuid(uid).pw_name
    except KeyError:
        user = f"uid {uid}"
    return f"local:{user} pid {pid}"


class LocalServer:
    """The io process's end: `status(q)` and `command(q, sender)` answer through the
    query's `reply` (from this thread, or later from the io loop's: a verdict)."""

    def __init__(self, path: str, hello: JsonObject, status: Handler,
                 command: Callable[[Query, str], None], key_of: Callable[[str], str],
                 status_key: str) -> None:
        self.path = path
        self.rig = hello.get("rig")
        self.hello = json.dumps({"ok": True, **hello}).encode() + b"\n"
        self.status = status
        self.command = command
        self.key_of = key_of  # verb -> its key (pamd/<rig>/cmd/<verb>)
        self.status_key = status_key
        self.sock: socket.socket | None = None
        self.conns: dict[int, _Conn] = {}
        self.refused = 0  # connections closed at once (more than MAX_CONNECTIONS)
        self._stop_r, self._stop_w = os.pipe()
        self._thread: threading.Thread | None = None
        self._ino = -1

    def open(self) -> str | None:
        """Listen; a note for the status when it cannot (None: it listens)."""
        if len(os.fsencode(self.path)) > MAX_PATH_BYTES:
            return f"no local channel: its path is longer than a Unix socket takes ({self.path})"
        clear_stale(os.path.dirname(self.path), str(self.rig))
        if os.path.exists(self.path):
            return f"no local channel: {self.path} is another daemon's"
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            sock.bind(self.path)  # in the token's directory: private until the chmod
            os.chmod(self.path, SOCKET_MODE)
            sock.listen(MAX_CONNECTIONS)
            sock.setblocking(False)
            self._ino = os.stat(self.path).st_ino
        except OSError as exc:
            sock.close()
            return f"no local channel at {self.path}: {exc.strerror or exc}"
        self.sock = sock
        self._thread = threading.Thread(target=self._run, name="pamd-local", daemon=True)
        self._thread.start()
        return None

    def close(self) -> None:
        if self.sock is None:
            return
        os.write(self._stop_w, b"x")
        if self._thread is not None:
            self._thread.join(2.0)
        with contextlib.suppress(OSError):
            if os.stat(self.path).st_ino == self._ino:  # still ours
                os.unlink(self.path)
        self.sock.close()
        self.sock = None
        for c in self.conns.values():
            c.sock.close()
        self.conns.clear()
        os.close(self._stop_r)
        os.close(self._stop_w)

    # -- its thread -----------------------------------------------------------------------
    def _run(self) -> None:
        assert self.sock is not None
        listen = self.sock
        while True:
            fds = [self._stop_r, listen.fileno(), *self.conns]
            try:
                ready, _, _ = select.select(fds, [], [], 1.0)
            except (OSError, ValueError):
                ready = []
            if self._stop_r in ready:
                return
            if listen.fileno() in ready:
                self._accept(listen)
            for fd in ready:
                c = self.conns.get(fd)
                if c is not None:
                    self._read(fd, c)
            self._reap(time.monotonic())

    def _accept(self, listen: socket.socket) -> None:
        try:
            sock, _ = listen.accept()
        except OSError:
            return
        if len(self.conns) >= MAX_CONNECTIONS:
            self.refused += 1
            sock.close()
            return
        sock.setblocking(False)
        self.conns[sock.fileno()] = _Conn(sock, peer_name(sock))

    def _reap(self, now: float) -> None:
        for fd, c in list(self.conns.items()):
            if c.dead or now - c.t > IDLE_S:
                del self.conns[fd]
                c.sock.close()

    def _read(self, fd: int, c: _Conn) -> None:
        try:
            data = c.sock.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            c.dead = True
            return
        if c.ending:
            return
        c.buf += data
        c.t = time.monotonic()
        while not c.dead and not c.ending and (req := self._request(c)) is not None:
            self._answer(c, *req)

    @staticmethod
    def _refuse(c: _Conn, text: str) -> None:
        """Say why, then end the connection (the peer reads the refusal, then its end)."""
        c.send(_error(text))
        c.ending, c.buf = True, b""
        with contextlib.suppress(OSError):
            c.sock.shutdown(socket.SHUT_WR)

    def _request(self, c: _Conn) -> tuple[JsonObject, bytes] | None:
        """The next whole request in the connection's buffer, or None."""
        line, nl, rest = c.buf.partition(b"\n")
        if not nl:
            if len(c.buf) > MAX_HEADER_BYTES:
                self._refuse(c, f"a request's header is one JSON line of at most "
                             f"{MAX_HEADER_BYTES} bytes")
            return None
        try:
            head = json.loads(line)
            n = int(head.get("n", 0))
        except (ValueError, TypeError, AttributeError):
            self._refuse(c, "a request's header is a JSON object")
            return None
        if not 0 <= n <= MAX_BODY_BYTES:
            self._refuse(c, f"a payload of at most {MAX_BODY_BYTES} bytes")
            return None
        if len(rest) < n:
            return None
        c.buf = rest[n:]
        return head, rest[:n]

    def _answer(self, c: _Conn, head: JsonObject, body: bytes) -> None:
        op = head.get("op")
        if op == "hello":
            c.send(self.hello)
        elif op == "status":
            self.status(LocalQuery(c, self.status_key, b"", ""))
        elif op == "cmd":
            verb = str(head.get("verb", ""))[:64]
            q = LocalQuery(c, self.key_of(verb), body, str(head.get("user", ""))[:64])
            self.command(q, c.sender)
        else:
            c.send(_error("op is hello, status or cmd"))


def _error(text: str) -> bytes:
    return json.dumps({"ok": False, "error": f"local channel: {text}"}).encode() + b"\n"


def _owner(path: str) -> str | None:
    """Who answers on the socket at `path` ("pid N"), or None if nobody does."""
    try:
        with LocalClient(path, 1.0) as c:
            return f"pid {c.hello().get('pid')}"
    except (NoDaemon, OSError, ValueError):
        return None


# -- the client (pamd status, pamd cmd) -------------------------------------------------
class LocalClient:
    """One connection to a daemon's local channel. NoDaemon when it does not answer."""

    def __init__(self, path: str, timeout_s: float = 3.0) -> None:
        self.path = path
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.settimeout(timeout_s)
        self.buf = b""
        try:
            self.sock.connect(path)
        except OSError as exc:
            self.sock.close()
            raise NoDaemon(f"no daemon answers on {path} ({exc.strerror or exc})") from None

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> LocalClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request(self, head: JsonObject, body: bytes = b"", timeout_s: float = 3.0
                ) -> JsonObject:
        self.sock.settimeout(timeout_s)
        try:
            self.sock.sendall(json.dumps({**head, "n": len(body)}).encode() + b"\n" + body)
            while b"\n" not in self.buf:
                chunk = self.sock.recv(65536)
                if not chunk:
                    raise NoDaemon(f"the daemon closed its local channel ({self.path})")
                self.buf += chunk
        except TimeoutError:
            raise NoDaemon(f"no answer within {timeout_s:g} s on {self.path}") from None
        except OSError as exc:
            raise NoDaemon(f"the local channel {self.path} failed: {exc}") from None
        line, _, self.buf = self.buf.partition(b"\n")
        answer: JsonObject = json.loads(line)
        return answer

    def hello(self) -> JsonObject:
        return self.request({"op": "hello"}, timeout_s=1.0)

    def status(self, timeout_s: float = 3.0) -> JsonObject:
        return self.request({"op": "status"}, timeout_s=timeout_s)

    def command(self, verb: str, body: bytes, user: str, timeout_s: float = 10.0
                ) -> JsonObject:
        return self.request({"op": "cmd", "verb": verb, "user": user}, body, timeout_s)


def socket_paths(rig: str | None) -> list[str]:
    """The local channels' sockets of `rig`'s daemons (None: of every rig) where daemons
    make them (pamd.wire.credential's token directories and /run/pamd)."""
    out: list[str] = []
    for d in dict.fromkeys([*token_dirs(), SERVICE_DIR]):
        out += [p for p in _rig_sockets(d, rig) if p not in out]
    return out

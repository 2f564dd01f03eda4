"""A socketcand server for the emulated rig's CAN bus: a CAN bus carried over a TCP
socket in socketcand's ASCII protocol (https://github.com/linux-can/socketcand, its
doc/protocol.md), so the daemon reaches the emulated encoders through python-can's own
`socketcand` client interface instead of a pty.

Why not a pty: a pty's bytes pass the kernel's tty layer, whose workers run at normal
priority; beside CPU hogs they delivered up to 91 ms late between two SCHED_FIFO threads
(bench/pty_delivery.py) while a loopback socket delivered within a few ms, and the
emulated rig's encoders went stale for it. A real rig's CAN adapter (socketcan) does not
pass the tty layer either.

The server plays one bus (`bus_name`, e.g. "can0") in raw mode, as socketcand does:
    server: < hi >                         client: < open can0 >
    server: < ok >                         client: < rawmode >
    server: < ok >
then every frame on the bus goes to every client as
`< frame ID SECONDS.MICROS DATA >` (ID 3 hex digits for an 11-bit id, 8 for a 29-bit
one; DATA the bytes in hex, no spaces), and a client's `< send ID LEN B0 B1 ... >` puts
a frame on the bus: the emulated devices (a python-can `virtual` bus in this process,
`local_channel`) and every other client see it, the sender does not (a CAN controller
does not receive its own frames). `< echo >` is answered with `< echo >`; other
commands (bcmmode, isotpmode, controlmode, filters) are answered `< error ... >`.

Each client has a reader thread and the bus one forwarding thread; they inherit the
emulator's scheduling (`pamd emulate --realtime-priority`). TCP_NODELAY on every
connection: a frame is one small segment, sent at once.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable

import can

#: socketcand's default TCP port
DEFAULT_PORT = 29536
#: a client that does not take a frame within this long is dropped (a wedged reader
#: must not hold up the bus for the other clients)
SEND_TIMEOUT_S = 1.0
#: after "< ok >" to rawmode, frames are held back this long (or until the client's
#: next command): python-can's client reads that answer with one recv() and refuses
#: anything more in it (it then raises CanError and the driver re-opens the bus)
RAW_GRACE_S = 0.05
#: longest command line accepted before the connection is taken for garbage
MAX_COMMAND = 256


def frame_text(msg: can.Message, stamp_s: float) -> str:
    """A received frame in socketcand's words."""
    cid = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    return f"< frame {cid} {stamp_s:.6f} {bytes(msg.data).hex().upper()} >"


def parse_send(words: list[str]) -> can.Message:
    """`< send ID LEN B0 ... >`'s words after "send" -> a frame; ValueError if malformed."""
    if len(words) < 2:
        raise ValueError("send needs an id and a length")
    cid, length = int(words[0], 16), int(words[1], 16)
    data = bytes(int(b, 16) for b in words[2:])
    if not 0 <= length <= 8 or len(data) != length:
        raise ValueError(f"length {length} does not match {len(data)} data bytes")
    extended = len(words[0]) > 3
    if cid > (0x1FFFFFFF if extended else 0x7FF):
        raise ValueError(f"id {words[0]} out of range")
    return can.Message(arbitration_id=cid, data=data, is_extended_id=extended)


class _Client:
    def __init__(self, sock: socket.socket, peer: str) -> None:
        self.sock = sock
        self.peer = peer
        self.raw = False  # frames flow once the client asked for raw mode ...
        self.raw_from = 0.0  # ... and from this time (time.monotonic) on
        self.lock = threading.Lock()
        self.alive = True

    def send(self, text: str) -> bool:
        if not self.alive:
            return False
        try:
            with self.lock:
                self.sock.sendall(text.encode("ascii"))
        except OSError:
            self.alive = False
            with contextlib.suppress(OSError):
                self.sock.shutdown(socket.SHUT_RDWR)
        return self.alive


class SocketcandServer:
    """Serve the `virtual` CAN channel `local_channel` as socketcand bus `bus_name` on
    `host:port` (loopback). `start()`, `stop()`; `frames_in`/`frames_out` count the
    frames clients sent and the frames sent to clients."""

    def __init__(self, host: str, port: int, bus_name: str, local_channel: str,
                 clock: Callable[[], float] = time.time) -> None:
        self.host, self.port, self.bus_name = host, port, bus_name
        self.local_channel = local_channel
        self.clock = clock
        self.frames_in = 0
        self.frames_out = 0
        self.clients: list[_Client] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._bus: can.BusABC | None = None
        self._listener: socket.socket | None = None
        self._threads: list[threading.Thread] = []

    # -- life cycle -------------------------------------------------------------------------
    def start(self) -> None:
        self._bus = can.Bus(interface="virtual", channel=self.local_channel)
        ls = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        ls.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            ls.bind((self.host, self.port))
        except OSError:
            ls.close()
            self._bus.shutdown()
            raise
        ls.listen(4)
        ls.settimeout(0.1)  # the accept loop sees a stop within this
        self._listener = ls
        self._spawn(self._accept, "emu-socketcand-accept")
        self._spawn(self._forward, "emu-socketcand-bus")

    def stop(self) -> None:
        self._stop.set()
        with self._lock:
            clients = list(self.clients)
        for c in clients:
            c.alive = False
            with contextlib.suppress(OSError):
                c.sock.shutdown(socket.SHUT_RDWR)
        for t in self._threads:
            t.join(2.0)
        for c in clients:
            c.sock.close()
        if self._listener is not None:
            self._listener.close()
        if self._bus is not None:
            self._bus.shutdown()

    def _spawn(self, target: Callable[..., None], name: str, *args: object) -> None:
        t = threading.Thread(target=target, args=args, name=name, daemon=True)
        self._threads.append(t)
        t.start()

    # -- threads -------------------------------------------------------------------------
    def _accept(self) -> None:
        assert self._listener is not None
        while not self._stop.is_set():
            try:
                sock, addr = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            sock.settimeout(None)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.settimeout(SEND_TIMEOUT_S)
            client = _Client(sock, f"{addr[0]}:{addr[1]}")
            with self._lock:
                self.clients = [c for c in self.clients if c.alive] + [client]
            self._spawn(self._serve, f"emu-socketcand-{addr[1]}", client)

    def _forward(self) -> None:
        """Frames of the emulated devices to every client in raw mode."""
        assert self._bus is not None
        while not self._stop.is_set():
            msg = self._bus.recv(0.1)
            if msg is None:
                continue
            self._to_clients(msg, None)

    def _to_clients(self, msg: can.Message, sender: _Client | None) -> None:
        text = frame_text(msg, self.clock())
        with self._lock:
            now = time.monotonic()
            clients = [c for c in self.clients
                       if c.raw and c.alive and c is not sender and now >= c.raw_from]
        for c in clients:
            if c.send(text):
                self.frames_out += 1

    def _serve(self, client: _Client) -> None:
        """One client's commands: the handshake, then `send`s."""
        client.send("< hi >")
        buf = b""
        while not self._stop.is_set() and client.alive:
            try:
                chunk = client.sock.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                break
            if not chunk:
                break
            buf += chunk
            while True:
                start, end = buf.find(b"<"), buf.find(b">")
                if end < 0:
                    if len(buf) > MAX_COMMAND:  # no command ends: garbage
                        client.send("< error command too long >")
                        buf = b""
                    break
                if start < 0 or start > end:  # bytes outside < >: dropped
                    buf = buf[end + 1:]
                    continue
                self._command(client, buf[start + 1:end].decode("ascii", "replace").split())
                buf = buf[end + 1:]
        client.alive = False
        with self._lock:
            self.clients = [c for c in self.clients if c is not client]
        client.sock.close()

    def _command(self, client: _Client, words: list[str]) -> None:
        if not words:
            client.send("< error empty command >")
            return
        command, rest = words[0], words[1:]
        if client.raw:
            client.raw_from = 0.0  # it has read the "< ok >" to rawmode
        if command == "open":
            if rest == [self.bus_name]:
                client.send("< ok >")
            else:
                client.send(f"< error no such bus {' '.join(rest)} (this server has "
                            f"{self.bus_name}) >")
        elif command == "rawmode":
            # python-can's client takes this "< ok >" with one recv() that must hold
            # nothing else: frames follow once it has had time to read it, or once it
            # sent a command (then it has read it)
            client.raw_from = time.monotonic() + RAW_GRACE_S
            client.raw = True
            client.send("< ok >")
        elif command == "echo":
            client.send("< echo >")
        elif command == "send" and client.raw:
            try:
                msg = parse_send(rest)
            except ValueError as exc:
                client.send(f"< error bad send: {exc} >")
                return
            self.frames_in += 1
            assert self._bus is not None
            self._bus.send(msg)  # to the emulated devices
            self._to_clients(msg, client)  # and the other clients on the bus
        else:
            client.send(f"< error {command} is not served (raw mode only) >")

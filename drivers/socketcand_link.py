"""python-can's socketcand client, made fit for a driver's I/O thread in the loop's
process.

Its constructor retries a refused connect for 10 s without a pause
(`connect_to_server`), and then waits for the server's greeting with no time limit.
On a driver's thread that is 10 s of a core and of the interpreter lock the loop
needs, with the lost link's fault unreported meanwhile (seen: a server restarting
answered the driver's first look and refused the client's connect a moment later),
or a thread hung for good on a server that accepts and never speaks.
`one_connect_attempt` makes the client's connect one attempt with a time limit, and
leaves that limit on the socket: a greeting, read or send that does not come fails
after it, and the driver backs off and tries again. python-can also takes an empty
read (the server closed the connection) for no frame: `server_closed` asks the
socket."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_SWAP = threading.Lock()  # one bus made at a time while the client's connect is swapped


@contextmanager
def one_connect_attempt(timeout_s: float) -> Iterator[None]:
    """While a socketcand bus is made in this block: one connect, limited to
    `timeout_s`, the limit kept on the socket."""
    from can.interfaces.socketcand import socketcand as client

    def connect_once(sock: socket.socket, host: str, port: int) -> None:
        sock.settimeout(timeout_s)
        sock.connect((host, port))

    with _SWAP:
        retrying = client.connect_to_server
        setattr(client, "connect_to_server", connect_once)  # noqa: B010 - a module's function
        try:
            yield
        finally:
            setattr(client, "connect_to_server", retrying)  # noqa: B010


def server_closed(bus: object) -> bool:
    """True if python-can's socketcand client's connection was closed by the server (a
    read would return nothing). python-can does not say so (its client takes an empty
    read for no frame), so its socket is asked directly; False where it has none."""
    sock = getattr(bus, "_SocketCanDaemonBus__socket", None)
    if not isinstance(sock, socket.socket):
        return False
    try:
        return sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
    except BlockingIOError:
        return False
    except OSError:
        return True

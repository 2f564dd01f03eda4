"""A minimal WebSocket client on a plain socket (RFC 6455: handshake, masked frames
out, frames in), to send what no well-behaved Foxglove client would: garbage text and
binary frames, subscribes to channels that do not exist, pings under a storm. Used by
the adversarial tests and bench/net_storm.py; loopback only."""

from __future__ import annotations

import base64
import contextlib
import os
import socket
import struct
import time

SUBPROTOCOL = "foxglove.sdk.v1"  # the foxglove-sdk server's (it refuses a handshake without)
OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 1, 2, 8, 9, 10


class WS:
    def __init__(self, host: str, port: int, timeout_s: float = 5.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout_s)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                           f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: "
                           f"{SUBPROTOCOL}\r\n\r\n").encode())
        buf = b""
        while b"\r\n\r\n" not in buf:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("closed during the handshake")
            buf += chunk
        head, _, self.buf = buf.partition(b"\r\n\r\n")
        if b" 101 " not in head.split(b"\r\n")[0]:
            raise ConnectionError(head[:200].decode("latin-1"))

    def send(self, data: bytes | str, opcode: int = OP_TEXT) -> None:
        body = data.encode() if isinstance(data, str) else data
        mask = os.urandom(4)
        n = len(body)
        hdr = bytes([0x80 | opcode])
        if n < 126:
            hdr += bytes([0x80 | n])
        elif n < 65536:
            hdr += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            hdr += bytes([0x80 | 127]) + struct.pack(">Q", n)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(body))
        self.sock.sendall(hdr + mask + masked)

    def _read(self, n: int) -> bytes:
        while len(self.buf) < n:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise ConnectionError("closed")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def recv(self) -> tuple[int, bytes]:
        """The next frame (opcode, payload); socket.timeout if none in time."""
        b0, b1 = self._read(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._read(2))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._read(8))[0]
        return b0 & 0x0F, self._read(n)

    def ping_s(self, timeout_s: float = 5.0) -> float | None:
        """Round trip of a ping to its pong (other frames skipped); None if none came
        within `timeout_s`."""
        token = os.urandom(8)
        t0 = time.monotonic()
        self.send(token, OP_PING)
        self.sock.settimeout(timeout_s)
        try:
            while time.monotonic() - t0 < timeout_s:
                op, data = self.recv()
                if op == OP_PONG and data == token:
                    return time.monotonic() - t0
        except (TimeoutError, OSError):
            return None
        return None

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()

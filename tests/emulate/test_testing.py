"""`pamd.emulate.testing.free_port`: the servers the tests start take ports no
outgoing connection can take first, and never one another's."""

from __future__ import annotations

import socket

import pytest

from pamd.emulate.testing import DEFAULT_PORTS, EPHEMERAL_RANGE_FILE, free_port


@pytest.mark.skipif(not EPHEMERAL_RANGE_FILE.exists(), reason="Linux's ephemeral range only")
def test_free_ports_lie_below_the_ephemeral_range_never_repeat_and_bind() -> None:
    low = int(EPHEMERAL_RANGE_FILE.read_text().split()[0])
    ports = [free_port() for _ in range(300)]
    assert len(set(ports)) == len(ports)  # never handed out twice in a process
    assert all(1024 <= p < low for p in ports)  # where no connect() takes its local port
    assert not DEFAULT_PORTS & set(ports)
    for p in ports[:20]:  # free: a server binds it
        with socket.socket() as s:
            s.bind(("127.0.0.1", p))
            s.listen()

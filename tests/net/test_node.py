"""The io process's Zenoh node without a network (stand-ins for the session, the
queries and the shared block): a command that waits for the loop's verdict is
answered when the verdict is late and when the daemon stops; the liveliness token
goes first; closing never hangs on a session that will not close."""

from __future__ import annotations

import json
import threading
import time
from types import SimpleNamespace
from typing import Any

from pamd.iohost.node import NetNode
from pamd.iohost.process import RingCommandPort
from pamd.wire.net_spec import NetSpec


class Query:
    def __init__(self, key: str) -> None:
        self.key_expr = key
        self.replies: list[tuple[str, dict[str, Any]]] = []
        self.dropped = False

    def reply(self, key: str, body: bytes, encoding: str = "") -> None:
        self.replies.append((key, json.loads(body)))

    def drop(self) -> None:
        self.dropped = True


class Entity:
    def __init__(self, log: list[str], name: str, hang: threading.Event | None = None) -> None:
        self.log, self.name, self.hang = log, name, hang

    def undeclare(self) -> None:
        self.log.append(f"undeclare {self.name}")

    def close(self) -> None:
        if self.hang is not None:
            self.hang.wait(30)  # a session that will not close
        self.log.append("close session")


def node(log: list[str], hang: threading.Event | None = None) -> NetNode:
    spec = NetSpec(rig_id="sim", muscles=("m1",), zenoh_json="{}", every_ticks=10,
                   publish_period_s=0.01, command_rate_per_s=10.0, command_burst=5,
                   command_timeout_s=0.5)
    block = SimpleNamespace(t_start=lambda: 0.0, newest_f64=lambda i: None, loop_lost=lambda: 0)
    port = RingCommandPort(SimpleNamespace(commands=None))  # type: ignore[arg-type]
    n = NetNode(spec, SimpleNamespace(virtual=True, wall0_ns=0, clock0_s=0.0), block, port,
                lambda *a: log.append("recorded"))
    n.session = Entity(log, "session", hang)
    n.token = Entity(log, "token")
    n.status_q, n.cmd_q = Entity(log, "status"), Entity(log, "cmd")
    n.events_pub, n.pubs = SimpleNamespace(put=lambda *a, **k: None), []
    return n


def test_a_late_verdict_is_answered_and_a_stop_answers_what_waits() -> None:
    log: list[str] = []
    n = node(log)
    late, waiting = Query("pamd/sim/cmd/setpoint"), Query("pamd/sim/cmd/hold")
    n.intake.waiting[1] = (late, 0.0, "setpoint", None)
    n.intake.waiting[2] = (waiting, 1e9, "hold", None)
    n.poll(1.0)  # the first one's deadline has passed
    assert late.dropped and late.replies[0][1]["ok"] is False
    assert "no verdict from the loop within 0.5 s" in late.replies[0][1]["error"]
    assert not waiting.replies
    n.close("SIGTERM received")
    assert waiting.dropped and waiting.replies[0][0] == "pamd/sim/cmd/hold"
    err = waiting.replies[0][1]["error"]
    assert "stopped (SIGTERM received)" in err and "not applied" in err
    assert log.index("undeclare token") < log.index("close session")
    assert n.intake.waiting == {} and n.intake.closing


def test_close_does_not_hang_on_a_session_that_will_not_close() -> None:
    log: list[str] = []
    hang = threading.Event()
    n = node(log, hang)
    t0 = time.monotonic()
    n.close("stopped by the daemon")
    assert time.monotonic() - t0 < 10.0  # bounded (CLOSE_TIMEOUT_S), not the 30 s hang
    assert "undeclare token" in log and "close session" not in log
    hang.set()

"""The io process's command intake (`NetNode.on_command`) without a network: who may
command (the token; an estop from anyone), rig ids as names (a pattern refused, an
estop on a pattern acts), an estop or stop that always acts whatever its payload, and
refusals recorded one per kind per interval with the count of the others."""

from __future__ import annotations

import json
import threading
from types import SimpleNamespace
from typing import Any

import pytest

from pamd.iohost import node as node_mod
from pamd.iohost.node import NetNode
from pamd.wire.credential import Signer, digest
from pamd.wire.net_spec import NetSpec

TOKEN = "t" * 43
NONCE = "0123456789abcdef"  # the daemon's run nonce


class Bytes:
    def __init__(self, b: bytes) -> None:
        self.b = b

    def to_bytes(self) -> bytes:
        return self.b


class Query:
    def __init__(self, key: str, payload: bytes = b"{}", token: str | None = TOKEN,
                 zid: str = "abc", nonce: str = NONCE) -> None:
        self.key_expr = key
        self.parameters = {"user": "ana"}
        self.payload = Bytes(payload)
        self.attachment = None if token is None else Bytes(Signer(token).attachment(
            "sim", key.rsplit("/", 1)[-1], payload, nonce))
        self.source_info = SimpleNamespace(source_id=SimpleNamespace(zid=zid))
        self.replies: list[dict[str, Any]] = []

    def reply(self, key: str, body: bytes, encoding: str = "") -> None:
        self.replies.append(json.loads(body))

    def drop(self) -> None:
        pass


class Port:
    """The loop's mailbox: what was sent, each given the verdict ok at once."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.waiting: dict[int, Any] = {}
        self.sent: list[tuple[str, dict[str, Any], str]] = []

    def send(self, verb: str, payload: dict[str, Any] | None, sender: str, user: str = "",
             on_verdict: Any = None) -> int | None:
        self.sent.append((verb, dict(payload or {}), sender))
        if on_verdict is not None:
            on_verdict({"ok": True})
        return len(self.sent)


def make(**kw: Any) -> tuple[NetNode, Port, list[tuple[str, dict[str, Any]]]]:
    spec = NetSpec(rig_id="sim", muscles=("m1",), zenoh_json="{}", every_ticks=10,
                   publish_period_s=0.01, command_rate_per_s=1000.0, command_burst=1000,
                   command_timeout_s=5.0, token_sha256=digest(TOKEN),
                   token_file="/run/pamd/pamd-sim.token", run_nonce=NONCE, **kw)
    port = Port()
    recorded: list[tuple[str, dict[str, Any]]] = []
    n = NetNode(spec, SimpleNamespace(virtual=True, wall0_ns=0, clock0_s=0.0),
                SimpleNamespace(t_start=lambda: 0.0, newest_f64=lambda i: None,
                                loop_lost=lambda: 0), port,  # type: ignore[arg-type]
                lambda t, kind, data: recorded.append((kind, data)))
    n.events_pub = SimpleNamespace(put=lambda *a, **k: None)
    return n, port, recorded


def send(n: NetNode, q: Query) -> dict[str, Any]:
    n.intake.on_command(q)
    n.flush_records()
    assert len(q.replies) == 1, q.replies
    return q.replies[0]


def test_a_command_with_the_token_is_taken_and_its_verdict_names_the_rig() -> None:
    n, port, _ = make()
    v = send(n, Query("pamd/sim/cmd/hold"))
    assert v == {"ok": True, "rig": "sim"}
    assert port.sent == [("hold", {}, "zenoh:abc")]


def test_a_command_without_or_with_a_wrong_token_is_refused_and_recorded() -> None:
    n, port, recorded = make()
    for tok, why in ((None, "needs the daemon's command credential"),
                     ("w" * 43, "does not match"), (TOKEN[:-1], "does not match"),
                     ("", "does not match")):
        v = send(n, Query("pamd/sim/cmd/setpoint", b'{"muscle": "m1", "bar": 3.0}', tok))
        assert not v["ok"] and why in v["error"] and "credential" in v["error"], v
        assert "/run/pamd/pamd-sim.token" in v["error"] and v["rig"] == "sim"
    assert port.sent == []  # nothing reached the loop
    kinds = [(k, d.get("error", "")) for k, d in recorded]
    assert kinds and kinds[0][0] == "command" and "credential" in kinds[0][1]
    assert n.counts["no_credential"] == 4


def test_an_estop_acts_without_the_token_and_is_recorded_as_such() -> None:
    n, port, _ = make()
    v = send(n, Query("pamd/sim/cmd/estop", b'{"reason": "hand in"}', token=None))
    assert v["ok"], v
    assert port.sent == [("estop", {"reason": "hand in"}, "zenoh:abc (no credential)")]
    v = send(n, Query("pamd/sim/cmd/stop", b"{}", token=None))  # a stop needs it
    assert not v["ok"] and "credential" in v["error"]


def test_a_signed_command_cannot_be_replayed_nor_sent_to_another_run() -> None:
    """Issue 43: the token travelled in clear with every command; captured, it could be
    replayed until the file was deleted. A signature taken once is refused the second
    time; one made for another run of the daemon (its nonce) is refused with this run's
    nonce; the old clear form is refused as such. An estop acts whatever (recorded as
    sent without a credential)."""
    n, port, recorded = make()
    body = b'{"muscle": "m1", "bar": 3.0}'
    q = Query("pamd/sim/cmd/setpoint", body)
    assert send(n, q)["ok"]
    again = Query("pamd/sim/cmd/setpoint", body)
    again.attachment = q.attachment  # the same bytes, captured and sent again
    v = send(n, again)
    assert not v["ok"] and "taken already" in v["error"], v
    other = Query("pamd/sim/cmd/setpoint", body, nonce="ffffffffffffffff")
    v = send(n, other)
    assert not v["ok"] and "another run" in v["error"] and v["command_nonce"] == NONCE
    assert v["credential"] == "stale"
    tampered = Query("pamd/sim/cmd/setpoint", b'{"muscle": "m1", "bar": 5.0}')
    tampered.attachment = Query("pamd/sim/cmd/setpoint", body).attachment
    assert "does not match" in send(n, tampered)["error"]  # the payload is signed
    clear = Query("pamd/sim/cmd/hold")
    clear.attachment = Bytes(b"pamd-token:" + TOKEN.encode())
    v = send(n, clear)
    assert not v["ok"] and "in clear" in v["error"], v
    assert len(port.sent) == 1  # only the first reached the loop
    e = Query("pamd/sim/cmd/estop", b'{"reason": "r"}')
    assert send(n, e)["ok"]
    e2 = Query("pamd/sim/cmd/estop", b'{"reason": "r"}')
    e2.attachment = e.attachment
    assert send(n, e2)["ok"]  # a replayed estop still stops the rig...
    assert port.sent[-1][2] == "zenoh:abc (no credential)"  # ...recorded as unsigned


def test_a_wildcard_key_is_refused_like_a_wildcard_rig() -> None:
    """Issue 47: `pamd/<rig>/**/setpoint` with a valid signature was taken."""
    n, port, _ = make()
    for key in ("pamd/sim/**/setpoint", "pamd/sim/*/setpoint", "pamd/sim/cmd/**/setpoint"):
        v = send(n, Query(key, b'{"muscle": "m1", "bar": 3.0}'))
        assert not v["ok"] and "not the pattern" in v["error"], (key, v)
    assert port.sent == []
    assert send(n, Query("pamd/sim/**/estop"))["ok"]  # an estop acts on a pattern
    assert send(n, Query("pamd/sim/cmd/setpoint", b'{"muscle": "m1", "bar": 3.0}'))["ok"]


def test_the_local_channel_needs_no_signature_and_names_its_sender() -> None:
    n, port, _ = make()
    q = Query("pamd/sim/cmd/hold", token=None)
    n.intake.on_command(q, sender="local:ana pid 42", trusted=True)
    assert q.replies == [{"ok": True, "rig": "sim"}]
    assert port.sent == [("hold", {}, "local:ana pid 42")]


def test_rig_patterns_are_refused_but_an_estop_on_one_acts() -> None:
    n, port, _ = make()
    for key in ("pamd/*/cmd/setpoint", "pamd/s*/cmd/hold", "pamd/$*/cmd/stop"):
        v = send(n, Query(key, b'{"muscle": "m1", "bar": 3.0}'))
        assert not v["ok"] and "not the pattern" in v["error"], (key, v)
    assert port.sent == []
    assert send(n, Query("pamd/*/cmd/estop"))["ok"]
    assert [s[0] for s in port.sent] == ["estop"]


def test_an_estop_or_stop_acts_whatever_its_size_or_fields() -> None:
    n, port, recorded = make()
    big = json.dumps({"reason": "r" * 100_000, "extra": [1] * 1000}).encode()
    v = send(n, Query("pamd/sim/cmd/estop", big))
    assert v["ok"] and "reason cut from 100000 characters" in v["cut"], v
    verb, payload, _ = port.sent[-1]
    assert verb == "estop" and len(payload["reason"]) <= 260
    assert "fields dropped: extra" in payload["reason"]
    v = send(n, Query("pamd/sim/cmd/stop", b'{"why": "x", "pad": "' + b"p" * 2_000_000 + b'"}'))
    assert v["ok"] and "read in part" in v["cut"], v
    assert port.sent[-1][:2] == ("stop", {})
    assert send(n, Query("pamd/sim/cmd/estop", b"\xff not json"))["ok"]
    assert [k for k, _ in recorded].count("command_cut") >= 2  # what was cut, recorded
    # the same size is refused for any other verb, unread
    v = send(n, Query("pamd/sim/cmd/hold", big))
    assert not v["ok"] and "above the limit of 65536 bytes" in v["error"]


def test_a_flood_of_refusals_is_recorded_once_per_kind_per_interval_and_counted(
        monkeypatch: Any) -> None:
    clock = [100.0]
    monkeypatch.setattr(node_mod.time, "monotonic", lambda: clock[0])
    n, _port, recorded = make()
    for _ in range(500):
        send(n, Query("pamd/sim/cmd/setpoint", b"{not json"))
        send(n, Query("pamd/sim/cmd/hold", token=None))
    assert len(recorded) == 2  # one of each kind
    clock[0] += 1.5
    n.session = SimpleNamespace()  # poll works on an open node
    n.batcher.pending = 0
    n.poll(clock[0])
    rest = [d for k, d in recorded if k == "refusals"]
    assert sorted(d["refused_unrecorded"] for d in rest) == [499, 499], recorded
    assert len(recorded) == 4  # and nothing more, however long the flood


class SlowPort(Port):
    """A loop that has not given its verdict yet: `verdict()` gives it."""

    def send(self, verb: str, payload: dict[str, Any] | None, sender: str, user: str = "",
             on_verdict: Any = None) -> int | None:
        self.sent.append((verb, dict(payload or {}), sender))
        self.pending_verdict = on_verdict
        return len(self.sent)


def test_a_flood_of_estops_beyond_the_rate_joins_the_one_in_flight_and_all_are_answered(
        ) -> None:
    n, _port, recorded = make()
    port = SlowPort()
    n.intake.port = port
    n.intake.limiter.rate, n.intake.limiter.burst = 1.0, 1.0  # one at once, then the rate
    qs = [Query("pamd/sim/cmd/estop", b'{"reason": "flood"}', token=None) for _ in range(200)]
    for q in qs:
        n.intake.on_command(q)
    assert len(port.sent) == 1  # one reached the loop; the others wait on it
    assert n.counts["joined"] == 199 and not any(q.replies for q in qs)
    port.pending_verdict({"ok": True, "state": "ESTOP"})
    assert all(len(q.replies) == 1 and q.replies[0]["ok"] for q in qs)
    assert sum(bool(q.replies[0].get("joined")) for q in qs) == 199
    assert n.intake.waiting == {} and n.intake.joined == {}


def test_a_storm_of_status_queries_builds_one_answer_per_interval() -> None:
    n, _port, _ = make()
    reads = []

    def read() -> tuple[bytes, float]:
        reads.append(1)
        return json.dumps({"rig_id": "sim", "state": "IDLE"}).encode(), 0.01

    bodies = {n.answer.serve(read, 100.0 + i * 0.001, 100.0, None, n.counts)
              for i in range(1000)}  # 1000 queries in 1 s
    assert 45 <= len(reads) <= 51 and len(bodies) <= len(reads)  # one per 20 ms
    assert all(json.loads(b)["state"] == "IDLE" for b in bodies)


def test_the_status_says_the_nonce_the_local_channel_and_the_warnings(
        capsys: pytest.CaptureFixture[str]) -> None:
    from pamd.client.cli.net import print_status

    clear = "telemetry listens on tcp/0.0.0.0:7447 beyond loopback WITHOUT TLS (allowed)"
    n, _, _ = make(warnings=(clear,))
    body = json.loads(n.answer.body((b'{"rig_id": "sim", "state": "IDLE"}', 0.01), 0.0, 0.0,
                                    None, {}))
    assert body["command_nonce"] == NONCE and body["local_channel"] is None
    assert body["warnings"] == [clear]
    print_status(body)
    assert f"WARNING: {clear}" in capsys.readouterr().out

"""Issue 43, "the e-stop always gets through": 100 Zenoh sessions with no credential
filled the daemon's cap and `pamd status` and `pamd cmd estop` failed ("no daemon or
router to talk to", exit 7); leaked sessions of a dead daemon's clients reconnected to
the next daemon and filled its cap.

- The daemon's local channel (`pamd.wire.local_channel`) answers status and takes commands on
  the rig PC outside Zenoh: with the daemon's session cap full, `pamd status` answers
  and `pamd cmd estop` stops the rig (default run: a cap lowered to 8 with 12
  sessions; `-m slow`: 200 sessions against the shipped cap of 100). The estop's
  latency (send to the loop's tick) is measured in bench/net_estop_flood.py; here it
  only has to get through.
- A client's Zenoh session ends with its owner (closed or collected) and with its
  daemon: it does not reconnect by itself into the next daemon's cap.
- The channel's own bounds (connections, headers), its file mode, stale sockets.
- Rotating the token (`pamd token --rotate`): the running daemon takes it, a command
  signed with the old one is refused, a client reads the new one by itself.

Loopback only; every daemon ends with its test."""

from __future__ import annotations

import contextlib
import gc
import json
import os
import socket
import stat
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from pamd.client.remote import Client, local_rig
from pamd.wire import credential as cr
from pamd.wire import local_channel as lc
from pamd.wire.zconf import NoDaemon
from tests.net.conftest import RigProc, free_port, pamd_cli, wait_until

RIG = "sim"


def zenoh_session(endpoint: str) -> Any:
    """A bare client session (no credential): what a flood is made of."""
    import zenoh

    return zenoh.open(zenoh.Config.from_json5(json.dumps({
        "mode": "client", "connect": {"endpoints": [endpoint]},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}}})))


def flood(endpoint: str, n: int) -> tuple[list[Any], int]:
    """Up to `n` sessions without a credential; (the open ones, how many were refused)."""
    open_, refused = [], 0
    for _ in range(n):
        try:
            open_.append(zenoh_session(endpoint))
        except Exception:
            refused += 1
    return open_, refused


@pytest.fixture
def token_dir(monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The run's own token directory (short: a socket path has at most 107 bytes), for the
    daemon and every client of the test."""
    d = Path(tempfile.mkdtemp(prefix="pamd-lc-"))
    monkeypatch.setenv(cr.TOKEN_DIR_ENV, str(d))
    yield d
    for p in d.iterdir():
        p.unlink()
    d.rmdir()


def estop_through_a_flood(tmp: Path, max_sessions: int, sessions: int) -> RigProc:
    """A daemon whose Zenoh cap is full: status and estop through the local channel.
    The daemon, its cap free again, for more."""
    rig = RigProc(tmp, RIG, telemetry={"max_sessions": max_sessions})
    ep = rig.endpoint
    held: list[Any] = []
    try:
        rig.agent.call("subscribe", name="ev", key=f"pamd/{RIG}/events")
        held, refused = flood(ep, sessions)
        assert refused > 0, "the cap should be full"
        r = pamd_cli("status", "--connect", ep, "--no-local", "--timeout", "2")
        assert r.returncode == 7, (r.returncode, r.stderr)  # over Zenoh: locked out
        r = pamd_cli("status", "--connect", ep)
        assert r.returncode == 0 and "via the local channel" in r.stdout, r.stderr
        t_sent = time.time()
        r = pamd_cli("cmd", "--connect", ep, "estop", "--reason", "flood")
        assert r.returncode == 0 and json.loads(r.stdout)["ok"], r.stderr
        with local_rig(RIG, ep) as lr:  # type: ignore[union-attr]
            wait_until(lambda: (s := lr.status(RIG))["state"] == "ESTOP" and "flood" in
                       str(s.get("reason")), 20, "ESTOP, for the reason given")
        got = rig.agent.call("until", name="ev", kind="command", contains="estop",
                             seconds=20)
        assert got["met"], got
        data = got["msg"]["data"]
        assert data["ok"] and data["sender"].startswith("local:"), data
        assert got["msg"]["wall_s"] - t_sent < 30.0  # the CLI's start included
    except BaseException:
        rig.close()
        raise
    finally:
        for s in held:
            with contextlib.suppress(Exception):
                s.close()
    return rig


def test_status_and_estop_get_through_a_full_session_cap_and_a_token_rotates(
        tmp_path: Path, token_dir: Path) -> None:
    """(One daemon for both: the flood, then `pamd token --rotate`: the running daemon
    takes the new token, a command signed with the old one is refused, a client reads
    the new one by itself.)"""
    rig = estop_through_a_flood(tmp_path, max_sessions=8, sessions=12)
    try:
        with Client(connect=rig.endpoint) as c:
            assert c.command(RIG, "reset")["ok"]  # out of the flood's ESTOP, signed
            assert "HOLD" in c.command(RIG, "resume")["error"]  # signed, taken, refused
            old = cr.find_token(RIG)[0]
            assert old is not None
            r = pamd_cli("token", "--rig", RIG, "--rotate")
            assert r.returncode == 0 and "a new token" in r.stdout, r.stderr
            new = cr.find_token(RIG)[0]
            assert new is not None and new != old
            nonce = str(c.status(RIG)["command_nonce"])
            body = b"{}"

            def refused_old() -> bool:  # (the loop refuses a resume from IDLE till then)
                att = cr.Signer(old).attachment(RIG, "resume", body, nonce)
                [v] = [json.loads(x.ok.payload.to_bytes()) for x in c.session.get(
                    f"pamd/{RIG}/cmd/resume", payload=body, attachment=att, timeout=5.0)
                    if x.ok is not None]
                return not v["ok"] and v.get("credential") == "bad"

            wait_until(refused_old, 10, "the old token refused")
            assert c.command(RIG, "hold")["ok"]  # this client read the new token itself
    finally:
        rig.close()


@pytest.mark.slow
def test_status_and_estop_get_through_200_sessions(tmp_path: Path, token_dir: Path) -> None:
    estop_through_a_flood(tmp_path, max_sessions=100, sessions=200).close()


# -- a client's session lives no longer than its owner, nor than its daemon ---------------
def test_a_clients_session_ends_with_its_owner_and_with_its_daemon() -> None:
    import zenoh

    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"

    def daemon() -> Any:  # a stand-in for a daemon's session: a peer capped at 3
        return zenoh.open(zenoh.Config.from_json5(json.dumps({
            "mode": "peer", "listen": {"endpoints": [ep]}, "connect": {"endpoints": []},
            "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
            "transport": {"unicast": {"max_sessions": 3}}})))

    first = daemon()
    leaked = [Client(connect=ep) for _ in range(3)]  # a notebook's, never closed
    with pytest.raises(NoDaemon):
        Client(connect=ep)  # the cap is full
    first.close()  # the daemon dies
    wait_until(lambda: all(c.lost for c in leaked), 10, "the clients to see it gone")
    second = daemon()
    try:
        time.sleep(1.5)  # Zenoh's own retry would have reconnected by now
        fresh = [Client(connect=ep) for _ in range(3)]  # the leaked ones left room
        del fresh[0]  # collected without close(): its session ends with it
        gc.collect()
        wait_until(lambda: _opens(ep), 10, "room for another client")
    finally:
        second.close()


def _opens(ep: str) -> bool:
    try:
        Client(connect=ep).close()
    except NoDaemon:
        return False
    return True


# -- the channel itself ----------------------------------------------------------------
class Echo:
    """A LocalServer with handlers that answer at once."""

    def __init__(self, path: str) -> None:
        self.server = lc.LocalServer(
            path, {"rig": RIG, "pid": os.getpid(), "listen": ["tcp/127.0.0.1:7447"]},
            lambda q: q.reply("k", b'{"ok": true, "state": "IDLE"}'),
            lambda q, sender: q.reply("k", json.dumps(
                {"ok": True, "sender": sender, "key": str(q.key_expr),
                 "user": q.parameters.get("user"),
                 "n": len(q.payload.to_bytes()) if q.payload else 0}).encode()),
            lambda verb: f"pamd/{RIG}/cmd/{verb}", f"pamd/{RIG}/status")


def test_the_local_channel_answers_its_users_and_bounds_the_rest(token_dir: Path) -> None:
    stale = token_dir / f"pamd-{RIG}.999999.sock"  # a killed daemon's socket
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.bind(str(stale))
    s.close()
    path = str(token_dir / f"pamd-{RIG}.{os.getpid()}.sock")
    e = Echo(path)
    assert e.server.open() is None
    try:
        assert not stale.exists()  # nobody answered on it: removed
        assert stat.S_IMODE(os.stat(path).st_mode) == lc.SOCKET_MODE
        # another daemon of this rig on the PC (the lab's own, a test beside this one)
        # keeps its socket in the shared directories, also searched: count only ours
        assert [p for p in lc.socket_paths(RIG) if p.startswith(str(token_dir))] == [path]
        with lc.LocalClient(path) as c:
            assert c.hello()["rig"] == RIG
            assert c.status()["state"] == "IDLE"
            v = c.command("hold", b'{"x": 1}', "ana")
            assert v["key"] == f"pamd/{RIG}/cmd/hold" and v["user"] == "ana" and v["n"] == 8
            assert v["sender"].startswith("local:") and f"pid {os.getpid()}" in v["sender"]
        lr = local_rig(RIG, "tcp/127.0.0.1:7447")  # the daemon that listens there
        assert lr is not None and lr.rig(None) == RIG
        lr.close()
        assert local_rig(RIG, "tcp/127.0.0.1:7448") is None  # another daemon's endpoint
        assert local_rig(RIG, "tcp/10.0.0.5:7447") is None  # not this machine
        many = [socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                for _ in range(lc.MAX_CONNECTIONS + 4)]
        for m in many:
            m.connect(path)
        wait_until(lambda: e.server.refused >= 4, 10, "the connections beyond the bound")
        for m in many:
            m.close()
        wait_until(lambda: not e.server.conns, 10, "the closed connections gone")
        for junk in (b"x" * (lc.MAX_HEADER_BYTES + 10), b"[1, 2]\n", b'{"n": -1}\n'):
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as raw:
                raw.settimeout(5.0)
                raw.connect(path)
                raw.sendall(junk)
                answer = b""
                while chunk := raw.recv(4096):  # the refusal, then the end
                    answer += chunk
                assert b"local channel: " in answer and b'"ok": false' in answer, answer
    finally:
        e.server.close()
    assert not os.path.exists(path)  # its own socket, removed as it closes


def test_a_socket_path_too_long_or_taken_is_said_not_fatal(token_dir: Path) -> None:
    long_dir = token_dir / ("d" * 100)
    long_dir.mkdir()
    note = Echo(str(long_dir / "pamd-sim.1.sock")).server.open()
    assert note is not None and "longer than a Unix socket takes" in note
    long_dir.rmdir()
    path = str(token_dir / "pamd-sim.1.sock")
    first = Echo(path)
    assert first.server.open() is None
    try:
        note = Echo(path).server.open()
        assert note is not None and "another daemon's" in note
    finally:
        first.server.close()


def test_a_reply_to_a_peer_that_does_not_read_never_blocks(token_dir: Path) -> None:
    path = str(token_dir / "pamd-sim.2.sock")
    e = Echo(path)
    assert e.server.open() is None
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as raw:
            raw.connect(path)
            wait_until(lambda: len(e.server.conns) == 1, 10, "the connection")
            [conn] = e.server.conns.values()
            done = threading.Event()

            def spam() -> None:
                for _ in range(10_000):
                    conn.send(b"x" * 65536)
                done.set()

            threading.Thread(target=spam, daemon=True).start()
            assert done.wait(10.0) and conn.dead  # gave up on it, never waited
    finally:
        e.server.close()

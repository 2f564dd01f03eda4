"""The pieces of pamd.iohost without a network: configs secure by default, the state
encoding, rate limits, the status board, the CLI's payloads and the status snapshot."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from pamd.client.cli.net import _parse_bool, build_payload, verb_parser
from pamd.daemon.host.resolve import resolve
from pamd.iohost.ratelimit import RateLimiter
from pamd.loop.tick_timing import Histogram
from pamd.wire import zconf
from pamd.wire.board import Board
from pamd.wire.errors import ConfigError
from pamd.wire.net_spec import TelemetryRequest
from pamd.wire.telemetry import LOOP_COLUMNS, StateBatcher, decode, rows
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS, State, TickLayout

REPO = Path(__file__).resolve().parents[2]


def test_every_shipped_config_turns_scouting_off_and_names_endpoints() -> None:
    files = sorted((REPO / "config" / "zenoh").glob("*.json5"))
    assert {f.name for f in files} >= {"default.json5", "lab-router.json5"}
    for f in files:
        cfg = zconf.load_file(str(f))
        assert zconf.get(cfg, "scouting/multicast/enabled") is False, f
        assert zconf.get(cfg, "scouting/gossip/enabled") is False, f
        assert zconf.endpoints(cfg, "listen") or zconf.endpoints(cfg, "connect"), f
    default = zconf.load_file(str(REPO / "config" / "zenoh" / "default.json5"))
    assert zconf.endpoints(default, "listen") == [zconf.DEFAULT_LISTEN]
    assert zconf.DEFAULT_LISTEN == "tcp/127.0.0.1:7447"


def test_built_configs_are_secure_by_default(tmp_path: Path) -> None:
    d = zconf.daemon_config(None, "tcp/127.0.0.1:7999")
    assert zconf.get(d, "mode") == "peer" and zconf.endpoints(d, "listen") == [
        "tcp/127.0.0.1:7999"]
    c = zconf.client_config()
    assert zconf.get(c, "mode") == "client"
    assert zconf.endpoints(c, "connect") == ["tcp/127.0.0.1:7447"]
    for cfg in (d, c):
        assert zconf.get(cfg, "scouting/multicast/enabled") is False
        assert zconf.get(cfg, "scouting/gossip/enabled") is False
    # a file that leaves scouting unsaid gets it off; one that says on keeps it
    f = tmp_path / "z.json5"
    f.write_text('{mode: "peer", listen: {endpoints: ["tcp/0.0.0.0:7555"]}}')
    assert zconf.get(zconf.daemon_config(str(f)), "scouting/multicast/enabled") is False
    # a client given the daemon's file connects where the daemon listens
    cl = zconf.client_config(str(f))
    assert zconf.endpoints(cl, "connect") == ["tcp/127.0.0.1:7555"]
    assert zconf.endpoints(cl, "listen") == [] and zconf.get(cl, "mode") == "client"
    f.write_text('{mode: "peer", scouting: {multicast: {enabled: true}}}')
    assert zconf.get(zconf.daemon_config(str(f)), "scouting/multicast/enabled") is True
    with pytest.raises(ConfigError, match="router"):
        zconf.router_config(str(f))
    f.write_text('{mode: "peer", bogus: 1}')
    with pytest.raises(ConfigError, match="bogus"):
        zconf.daemon_config(str(f))
    with pytest.raises(ConfigError, match="no such file"):
        zconf.daemon_config(str(tmp_path / "missing.json5"))


def test_telemetry_request_resolves_from_the_config(sim_config: Any, tmp_path: Path) -> None:
    # enabled: null is the config default (the shared fixture turns telemetry off)
    auto = {"enabled": None, "rate_hz": 250.0, "listen": "tcp/127.0.0.1:7123"}
    assert resolve(sim_config(30.0, telemetry=auto), TelemetryRequest()) is None  # virtual
    assert resolve(sim_config(30.0, telemetry=auto, loop={"clock": "real"}),
                   TelemetryRequest()) is not None  # real clock: on by default
    cfg = sim_config(30.0, telemetry=dict(auto, enabled=True))
    assert resolve(cfg, None) is None  # the library default: off
    assert resolve(cfg, TelemetryRequest(enabled=False)) is None  # --no-telemetry
    spec = resolve(cfg, TelemetryRequest())
    assert spec is not None and spec.every_ticks == 4 and spec.muscles == ("m1",)
    assert "tcp/127.0.0.1:7123" in spec.zenoh_json
    assert resolve(sim_config(30.0, telemetry={"enabled": False}, loop={"clock": "real"}),
                   TelemetryRequest()) is None
    with pytest.raises(ConfigError, match="cannot be part of a Zenoh key"):
        resolve(sim_config(30.0, rig_id="a/b", telemetry={"enabled": True}),
                TelemetryRequest())
    with pytest.raises(ConfigError, match="no such file"):
        resolve(cfg, TelemetryRequest(zenoh_config=str(tmp_path / "none.json5")))


def test_listening_beyond_loopback_without_tls_must_be_said_and_is_warned(
        sim_config: Any, tmp_path: Path) -> None:
    """Issue 43: `pamd run --listen tcp/0.0.0.0:...` started without TLS and without a
    warning. Refused unless --allow-cleartext (or telemetry.allow_cleartext) says so,
    naming where the endpoint came from; allowed, warned (at start, in every status)."""
    on = {"enabled": True, "listen": "tcp/0.0.0.0:7123"}
    with pytest.raises(ConfigError, match="allow-cleartext") as err:
        resolve(sim_config(30.0, telemetry=on), TelemetryRequest())
    assert "telemetry.listen" in str(err.value) and "tcp/0.0.0.0:7123" in str(err.value)
    spec = resolve(sim_config(30.0, telemetry=on), TelemetryRequest(allow_cleartext=True))
    assert spec is not None and "WITHOUT TLS" in spec.warnings[0]
    spec = resolve(sim_config(30.0, telemetry=dict(on, allow_cleartext=True)),
                   TelemetryRequest())
    assert spec is not None and spec.warnings
    loopback = {"enabled": True, "listen": "tcp/127.0.0.1:7123"}
    with pytest.raises(ConfigError, match="--listen"):
        resolve(sim_config(30.0, telemetry=loopback),
                TelemetryRequest(listen="tcp/192.168.7.2:7124"))
    spec = resolve(sim_config(30.0, telemetry=loopback), TelemetryRequest())
    assert spec is not None and spec.warnings == ()  # loopback: nothing to say
    import zenoh

    cfg = zenoh.Config.from_json5(json.dumps({"listen": {"endpoints": [
        "tls/0.0.0.0:7447", "quic/0.0.0.0:7448", "tcp/127.0.0.1:1", "tcp/[::1]:2",
        "tcp/localhost:3", "unixsock-stream//tmp/z.sock", "tcp/192.168.1.4:5",
        "udp/0.0.0.0:6", "tcp/[::]:7"]}}))
    assert zconf.cleartext_beyond_loopback(cfg) == [
        "tcp/192.168.1.4:5", "udp/0.0.0.0:6", "tcp/[::]:7"]
    router = zconf.load_file(str(REPO / "config" / "zenoh" / "lab-router.json5"))
    assert zconf.cleartext_beyond_loopback(router) == []  # the shipped router: TLS


CLEAR = "beyond loopback WITHOUT TLS (allowed on purpose: pamd run --allow-cleartext, or " \
    "telemetry.allow_cleartext: true)"


def test_connecting_in_clear_beyond_loopback_is_judged_as_listening_is(
        sim_config: Any, tmp_path: Path) -> None:
    """Issue 43 item 2, completed: a daemon whose Zenoh config connects in clear (tcp/)
    to a router on another machine sends state, status and commands over the network
    as a listen in clear does: refused naming the file, line and key unless allowed,
    then warned in the same words; loopback and TLS connects say nothing."""
    def with_connect(endpoint: str) -> Any:
        (tmp_path / "lab.json5").write_text(
            '{\n  mode: "peer",\n  listen: {endpoints: ["tcp/127.0.0.1:7123"]},\n'
            f'  connect: {{endpoints: ["{endpoint}"]}},\n}}\n')
        return sim_config(30.0, telemetry={"enabled": True, "zenoh_config": "lab.json5"})

    with pytest.raises(ConfigError) as err:
        resolve(with_connect("tcp/192.168.7.2:7447"), TelemetryRequest())
    text = str(err.value)
    assert "lab.json5:4: connect/endpoints:" in text and "--allow-cleartext" in text, text
    assert "the Zenoh session connects to tcp/192.168.7.2:7447 beyond loopback without " \
        "TLS" in text, text
    spec = resolve(with_connect("tcp/192.168.7.2:7447"), TelemetryRequest(allow_cleartext=True))
    assert spec is not None and spec.warnings == (
        f"the Zenoh session connects to tcp/192.168.7.2:7447 {CLEAR}: state, status and "
        "signed commands can be read on the network",)
    for fine in ("tls/lab-router:7447", "tcp/localhost:7447", "quic/10.0.0.1:7447"):
        spec = resolve(with_connect(fine), TelemetryRequest())
        assert spec is not None and spec.warnings == (), fine


def test_the_foxglove_view_beyond_loopback_needs_tls_or_the_same_permission(
        sim_config: Any) -> None:
    """Issue 43 item 2, completed: the live view's WebSocket is plain unless it has a
    certificate; beyond loopback (0.0.0.0, a LAN address, a host name) it is refused
    like a Zenoh listen in clear, from the config (its line) or --foxglove, in one error
    with the Zenoh endpoint when both are; allowed, warned at start and in the status;
    with TLS (wss://) or on loopback, nothing to say."""
    from pamd.daemon.host.resolve import resolve_all

    lan = {"foxglove": {"enabled": True, "listen": "0.0.0.0:8765"}}
    with pytest.raises(ConfigError) as err:
        resolve_all(sim_config(30.0, telemetry=lan), TelemetryRequest())
    text = str(err.value)
    line = next(i for i, ln in enumerate(
        sim_config(30.0, telemetry=lan).text.splitlines(), 1) if "0.0.0.0:8765" in ln)
    assert f"sim.yaml:{line}: telemetry.foxglove.listen:" in text, text
    assert "the Foxglove live view serves on ws://0.0.0.0:8765 beyond loopback without TLS" in text
    assert "telemetry.foxglove.tls_cert" in text and "--allow-cleartext" in text
    with pytest.raises(ConfigError) as err:  # both at once: one error names both
        resolve_all(sim_config(30.0), TelemetryRequest(
            foxglove="lab-pc.local:8765", listen="tcp/0.0.0.0:7123"))
    assert "--foxglove" in str(err.value) and "--listen" in str(err.value)
    assert len(err.value.issues) == 2
    got = resolve_all(sim_config(30.0), TelemetryRequest(
        foxglove="0.0.0.0:8765", listen="tcp/0.0.0.0:7123", allow_cleartext=True))
    assert got.net is not None and got.net.warnings == got.warnings == (
        f"the Zenoh session listens on tcp/0.0.0.0:7123 {CLEAR}: state, status and signed "
        "commands can be read on the network",
        f"the Foxglove live view serves on ws://0.0.0.0:8765 {CLEAR}: the live state, loop "
        "timing and events can be read on the network")
    got = resolve_all(sim_config(30.0, telemetry=dict(lan, allow_cleartext=True)),
                      TelemetryRequest())  # telemetry off (virtual clock): said at start
    assert got.net is None and got.viewer is not None and len(got.warnings) == 1
    for host in ("127.0.0.1", "localhost", "[::1]"):
        got = resolve_all(sim_config(30.0), TelemetryRequest(foxglove=f"{host}:8765"))
        assert got.viewer is not None and got.warnings == (), host


def test_the_foxglove_certificate_and_key_are_checked_before_anything_starts(
        sim_config: Any, tmp_path: Path) -> None:
    from pamd.daemon.host.resolve import resolve_all

    (tmp_path / "view.pem").write_bytes(b"-----BEGIN CERTIFICATE-----\nMII...\n")
    (tmp_path / "view.key").write_bytes(b"-----BEGIN PRIVATE KEY-----\nSECRET\n")
    (tmp_path / "rsa.key").write_bytes(b"-----BEGIN RSA PRIVATE KEY-----\nMII...\n")
    tls = {"enabled": True, "listen": "0.0.0.0:8765", "tls_cert": "view.pem",
           "tls_key": "view.key"}
    got = resolve_all(sim_config(30.0, telemetry={"foxglove": tls}), TelemetryRequest())
    assert got.viewer is not None and got.viewer.url == "wss://0.0.0.0:8765"
    assert got.warnings == () and got.viewer.tls_key is not None
    assert "SECRET" not in repr(got.viewer)  # the key is never printed
    for change, says in (({"tls_key": None}, "telemetry.foxglove.tls_key: expected a PEM "
                          "PKCS#8 private key"),
                         ({"tls_key": "rsa.key"}, "openssl pkcs8 -topk8"),
                         ({"tls_cert": "none.pem"}, "telemetry.foxglove.tls_cert: expected a "
                          "PEM certificate file")):
        with pytest.raises(ConfigError, match=says):
            resolve_all(sim_config(30.0, telemetry={"foxglove": dict(tls, **change)}),
                        TelemetryRequest())


def test_the_router_judges_its_links_by_the_same_rule(tmp_path: Path) -> None:
    """`pamd router`: a listen or a connect in clear beyond loopback is refused naming
    the file's line, in the rule's words, before any session opens."""
    import argparse

    from pamd.client.cli.router import run

    conf = tmp_path / "router.json5"
    conf.write_text('{\n  mode: "router",\n  listen: {endpoints: ["tcp/0.0.0.0:7447"]},\n'
                    '  connect: {endpoints: ["tcp/10.1.2.3:7447"]},\n}\n')
    with pytest.raises(ConfigError) as err:
        run(argparse.Namespace(zenoh_config=str(conf), duration=0.0, allow_cleartext=False))
    text = str(err.value)
    assert "router.json5:3: listen/endpoints:" in text and "router.json5:4: connect/" \
        "endpoints:" in text, text
    assert "the router connects to tcp/10.1.2.3:7447 beyond loopback without TLS" in text
    assert "say it: pamd router --allow-cleartext" in text


def test_the_io_session_says_the_allowed_links_in_clear_at_start(
        sim_config: Any, caplog: pytest.LogCaptureFixture) -> None:
    """The start says each warning, the live view's too with telemetry off (the status
    says them from NetSpec.warnings: test_intake)."""
    from pamd.daemon.host.resolve import resolve_all
    from pamd.daemon.io_session import IoSession

    got = resolve_all(sim_config(30.0), TelemetryRequest(foxglove="0.0.0.0:8765",
                                                         allow_cleartext=True))

    class Link:
        def start(self) -> None:
            pass

    session = IoSession.__new__(IoSession)  # no io process: what `start` says only
    session.link, session.board, session.net = Link(), None, None  # type: ignore[assignment]
    session.viewer, session.warnings = got.viewer, got.warnings
    with caplog.at_level("WARNING", logger="pamd"):
        session.start()
    assert [r.getMessage() for r in caplog.records if r.levelname == "WARNING"] == [
        f"the Foxglove live view serves on ws://0.0.0.0:8765 {CLEAR}: the live state, loop "
        "timing and events can be read on the network"]


def test_a_restart_in_place_keeps_the_permission_to_run_in_clear() -> None:
    from pamd.client.cli.main import build_parser
    from pamd.daemon.service.restart import run_argv

    args = build_parser().parse_args(["run", "--listen", "tcp/0.0.0.0:7447",
                                      "--allow-cleartext"])
    assert "--allow-cleartext" in run_argv(args, remaining_s=None)


def test_pamd_run_refuses_to_listen_in_clear_beyond_loopback(tmp_path: Path) -> None:
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--clock", "virtual",
                        "--duration", "1", "--no-record", "--listen", "tcp/0.0.0.0:7999"],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "--allow-cleartext" in r.stderr and "without TLS" in r.stderr, r.stderr


def test_state_batches_decimate_and_stay_strict_json() -> None:
    layout = TickLayout(["m1", "m2"])
    b = StateBatcher("sim", layout.muscles, every_ticks=10)
    for tick in range(35):
        rec = layout.new_record()
        rec[0], rec[1], rec[LOOP_FIELDS.index("state")] = tick, tick * 0.001, 2
        rec[layout.muscle_index(0, "pressure_bar")] = 1.0 + tick
        rec[layout.muscle_index(1, "length_mm")] = math.nan
        b.add(tuple(rec))
    assert b.pending == 4  # ticks 0, 10, 20, 30
    m1 = decode(b.batches[0].take(1000.0))
    m2 = json.loads(b.batches[1].take(None))  # strict JSON: NaN became null
    assert m1["muscle"] == "m1" and m1["rig"] == "sim" and m1["seq"] == 0
    assert m1["tick"] == [0, 10, 20, 30] and m1["pressure_bar"] == [1.0, 11.0, 21.0, 31.0]
    assert set(m1) >= set(LOOP_COLUMNS) | set(MUSCLE_FIELDS) and m1["t0_wall_s"] == 1000.0
    assert m2["length_mm"] == [None] * 4
    assert rows(m1)[2]["pressure_bar"] == 21.0 and rows(m1)[2]["tick"] == 20
    assert b.batches[0].take(None).count(b"[]") == len(LOOP_COLUMNS) + len(MUSCLE_FIELDS)


def test_rate_limit_per_sender_and_for_all() -> None:
    rl = RateLimiter(rate_per_s=2.0, burst=3, global_factor=2.0)
    assert [rl.allow("a", 0.0) for _ in range(4)] == [True, True, True, False]
    assert rl.allow("a", 0.5)  # one token back after 0.5 s at 2/s
    assert not rl.allow("a", 0.5)
    # everyone together: 4/s, burst 6; 4 taken by a, 1 back after 0.5 s
    assert [rl.allow("b", 0.5) for _ in range(3)] == [True, True, True]
    assert [rl.allow("c", 0.5) for _ in range(2)] == [True, False]  # c has tokens, all not
    assert rl.refused == 3


def test_status_board_round_trip() -> None:
    owner = Board(create=True)
    reader = Board(owner.name)
    try:
        assert reader.read_status() is None and reader.stopping() is None
        owner.write_status(b'{"state": "IDLE"}')
        owner.write_status(b'{"state": "RUNNING"}')
        blob, age = reader.read_status()  # type: ignore[misc]
        assert json.loads(blob) == {"state": "RUNNING"} and 0.0 <= age < 5.0
        assert not owner.write_status(b"x" * (64 * 1024 + 1))
        owner.set_stopping("SIGTERM received")
        assert reader.stopping() == "SIGTERM received"
        assert reader.requests.put_blob(b'{"id": 1}')
        assert owner.requests.get_blob() == b'{"id": 1}'
        assert owner.replies.put_blob(b'{"id": 1, "verdict": {"ok": true}}')
        assert json.loads(reader.replies.get_blob() or b"")["verdict"]["ok"] is True
    finally:
        reader.close()
        owner.close()


def test_cmd_payloads_from_options() -> None:
    p = build_payload("setpoint", ["--muscle", "m1", "--bar", "3", "--deadman-s", "0.5"],
                      verb_parser("setpoint").parse_args([]))
    assert p == {"muscle": "m1", "bar": 3.0, "deadman_s": 0.5}
    p = build_payload("profile", ["--kind", "sine", "--cycles", "2", "--max-bar", "4"],
                      verb_parser("profile").parse_args([]))
    assert p == {"shape": "sine", "cycles": 2, "max_bar": 4.0}
    p = build_payload("profile", ["--shape", "sine", "--cycles", "2", "--max-bar", "4"],
                      verb_parser("profile").parse_args([]))  # the new name, and the old one
    assert p == {"shape": "sine", "cycles": 2, "max_bar": 4.0}
    assert _parse_bool("false") is False and _parse_bool("On") is True
    p = build_payload("load", ["--arg", "muscle=m1", "--arg", "load_kg=40"],
                      verb_parser("load").parse_args([]))
    assert p == {"muscle": "m1", "load_kg": 40}
    raw = build_payload("setpoint", ["--json", '{"bar": NaN'],
                        verb_parser("setpoint").parse_args([]))
    assert raw == '{"bar": NaN'  # sent as given: the daemon says what is wrong
    with pytest.raises(SystemExit):
        build_payload("setpoint", ["--speed", "3"], verb_parser("setpoint").parse_args([]))


def test_status_snapshot_from_a_running_daemon(sim_daemon: Any) -> None:
    from pamd.daemon.host.snapshot import StatusBuilder, recording_status
    from pamd.iohost.answer import TickStats
    from pamd.wire.status import MUSCLE_STATUS_FIELDS, STATUS_FIELDS

    d = sim_daemon(duration_s=None)
    assert d.wait_for_state((State.IDLE,)) == State.IDLE
    st = StatusBuilder(d.ctrl, d.loop, lambda: d.cfg, lambda: recording_status(d.io)).build(0.0)
    json.dumps(st, allow_nan=False)  # strict JSON
    # every declared field, and only those (pamd.wire.status declares them)
    assert tuple(st) == STATUS_FIELDS and tuple(st["muscles"]["m1"]) == MUSCLE_STATUS_FIELDS
    assert st["rig_id"] == "sim" and st["config_sha256"] == d.cfg.sha256
    m1 = st["muscles"]["m1"]
    assert m1["has_length_datum"] is True and m1["datums"]["has_length_datum"] is True
    # the deprecated old names, served beside the new ones with the same values
    assert m1["referenced"] is m1["has_length_datum"]
    assert m1["references"] == {"length_referenced" if k == "has_length_datum" else k: v
                                for k, v in m1["datums"].items()}
    # the model's watch as the run summary has it (no model ran: nothing judged)
    assert st["muscles"]["m1"]["feedforward"] == {
        "off_data": "fade", "off_data_pct": None, "faded_pct": None,
        "oscillating_pct": None, "oscillations": 0, "ticks": 0}
    assert "setpoint" in st["verbs"] and "timing" not in st  # the io process adds it
    # the io process's timing statistics agree with the loop's own histogram
    stats, hist = TickStats(period_s=0.0), Histogram()
    rows = []
    for k, (w, c) in enumerate([(20e-6, 50e-6), (35e-6, 60e-6), (900e-6, 70e-6)] * 40):
        rec = d.layout.new_record()
        rec[0], rec[2], rec[3] = k, w, c
        rows.append(tuple(rec))
        hist.add(w)
    stats.add(rows)
    stats.refresh(1.0)
    t = stats.summary
    assert t["ticks"] == 120 and t["wake_latency_us"]["max"] == 900.0
    assert [t["wake_latency_us"]["p50"], t["wake_latency_us"]["p99"]] == [
        hist.percentile_s(50) * 1e6, hist.percentile_s(99) * 1e6]

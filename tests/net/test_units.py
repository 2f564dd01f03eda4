"""The pieces of pamd.net without a network: configs secure by default, the state
encoding, rate limits, the status board, the CLI's payloads and the status snapshot."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from pamd.cli.net import _parse_bool, build_payload, verb_parser
from pamd.errors import ConfigError
from pamd.net import zconf
from pamd.net.board import Board
from pamd.net.host.resolve import resolve
from pamd.net.ratelimit import RateLimiter
from pamd.net.spec import TelemetryRequest
from pamd.net.telemetry import LOOP_COLUMNS, StateBatcher, decode, rows
from pamd.tick import LOOP_FIELDS, MUSCLE_FIELDS, State, TickLayout
from pamd.timing import Histogram

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
    assert p == {"kind": "sine", "cycles": 2, "max_bar": 4.0}
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
    from pamd.net.host.status import StatusBuilder, recording_status
    from pamd.net.node.answer import TickStats
    from pamd.net.status import MUSCLE_STATUS_FIELDS, STATUS_FIELDS

    d = sim_daemon(duration_s=None)
    assert d.wait_for_state((State.IDLE,)) == State.IDLE
    st = StatusBuilder(d.ctrl, d.loop, lambda: d.cfg, lambda: recording_status(d.io)).build(0.0)
    json.dumps(st, allow_nan=False)  # strict JSON
    # every declared field, and only those (pamd.net.status declares them)
    assert tuple(st) == STATUS_FIELDS and tuple(st["muscles"]["m1"]) == MUSCLE_STATUS_FIELDS
    assert st["rig_id"] == "sim" and st["config_sha256"] == d.cfg.sha256
    assert st["muscles"]["m1"]["references"]["length_referenced"] is True
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

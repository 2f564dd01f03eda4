"""The live Foxglove view of a running simulated rig, seen by the protocol's own client
library (@foxglove/ws-protocol under Node, not pamd's code): the recording's channels
and schemas, every decimated tick decoded from the advertised schema and equal to
what the recording holds; a stalled viewer that never blocks the loop; a taken port
refused before anything moves."""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.records import Channel, Schema

from pamd.iohost.recorder import record_schemas
from pamd.wire.record.files import Decoder
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS

from ..net.conftest import DaemonProc, free_port, rig_config
from .conftest import Viewer

SINE = ("--profile", "sine", "--min-bar", "1", "--max-bar", "3", "--freq-hz", "0.5")
TOPICS = ("/pamd/sim/state/m1", "/pamd/sim/loop", "/pamd/sim/events")


def recorded(rec: Path) -> tuple[dict[str, Any], dict[str, dict[int, tuple[int, bytes]]]]:
    """(topic -> (schema name, encoding, text, message encoding)), (topic -> log time ->
    (log time, data)) of the run's one recording file."""
    files = sorted(rec.glob("*.mcap"))
    assert len(files) == 1, files
    with open(files[0], "rb") as fh:
        r = make_reader(fh)
        summary = r.get_summary()
        assert summary is not None
        chans = {c.topic: (summary.schemas[c.schema_id].name,
                           summary.schemas[c.schema_id].encoding,
                           summary.schemas[c.schema_id].data.decode(), c.message_encoding)
                 for c in summary.channels.values()}
        msgs: dict[str, dict[int, tuple[int, bytes]]] = {t: {} for t in chans}
        for _s, ch, m in r.iter_messages():
            msgs[ch.topic][m.log_time] = (m.log_time, m.data)
    return chans, msgs


def recorded_events(rec: Path) -> list[tuple[int, bytes]]:
    (file,) = sorted(rec.glob("*.mcap"))
    with open(file, "rb") as fh:
        return [(m.log_time, m.data) for _s, _c, m in
                make_reader(fh).iter_messages(topics=["/pamd/sim/events"])]


def same(a: Any, b: float) -> bool:
    return (a == "NaN" and math.isnan(b)) or a == b


def test_a_foxglove_client_decodes_the_live_state_as_recorded(tmp_path: Path) -> None:
    port = free_port()
    cfg = rig_config(tmp_path, None)  # 500 Hz, telemetry.rate_hz 100: every 5th tick
    rec = tmp_path / "rec"
    viewer = Viewer(tmp_path, f"ws://127.0.0.1:{port}", "--topics", ",".join(TOPICS),
                    "--timeout", "120", "--connect-timeout", "60")
    daemon = DaemonProc(tmp_path, ["--config", str(cfg), "--record", str(rec),
                                   "--no-telemetry", "--foxglove", f"127.0.0.1:{port}", *SINE])
    try:
        viewer.wait_receiving()
        time.sleep(1.0)  # a second of state (how much does not matter)
        assert daemon.stop() == 0, daemon.log()
        out = viewer.result()  # the server closes when the daemon stops
    finally:
        viewer.kill()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    assert out["server"]["name"] == "pamd sim" and out["server"]["capabilities"] == []
    assert out["errors"] == ["connection closed by the server"], out["errors"]
    # the recording's channels and schemas, as advertised
    chans, msgs = recorded(rec)
    advertised = {c["topic"]: (c["schemaName"], c["schemaEncoding"], c["schema"], c["encoding"])
                  for c in out["channels"]}
    assert advertised == chans
    assert {n for n, _e, _d in record_schemas()} == {v[0] for v in chans.values()}
    # every 5th tick, none missing, each equal to the recorded message at its log time
    state = out["messages"]["/pamd/sim/state/m1"]
    assert len(state) >= 20, len(state)
    ticks = [s["body"]["tick"] for s in state]
    assert all(t % 5 == 0 for t in ticks)
    assert all(b - a == 5 for a, b in zip(ticks, ticks[1:], strict=False)), ticks[:50]
    assert list(state[0]["body"]) == ["tick", "t_s", *MUSCLE_FIELDS]
    name, enc, text, menc = chans["/pamd/sim/state/m1"]
    dec = Decoder()
    ch = Channel(id=1, topic="/pamd/sim/state/m1", message_encoding=menc, schema_id=1,
                 metadata={})
    sc = Schema(id=1, name=name, encoding=enc, data=text.encode())
    cols = dec.columns(ch, sc)
    assert cols == ["tick", "t_s", *MUSCLE_FIELDS]
    for s in state:
        log_ns = int(s["log_ns"])
        assert log_ns in msgs["/pamd/sim/state/m1"], (s["body"]["tick"], log_ns)
        row = dec.decode(ch, sc, msgs["/pamd/sim/state/m1"][log_ns][1])
        assert row is not None
        for k, v in zip(cols, row, strict=True):
            assert same(s["body"][k], v), (s["body"]["tick"], k, s["body"][k], v)
    loop = out["messages"]["/pamd/sim/loop"]
    lticks = [m["body"]["tick"] for m in loop]  # subscribed a moment apart from the state
    assert all(b - a == 5 for a, b in zip(lticks, lticks[1:], strict=False))
    assert len(set(lticks) & set(ticks)) >= len(ticks) - 5
    assert list(loop[0]["body"]) == list(LOOP_FIELDS)
    # the stop's events, as the recording has them
    kinds = [(e["body"]["kind"], e["body"]["data"].get("to")) for e in
             out["messages"]["/pamd/sim/events"]]
    assert ("transition", "IDLE") in kinds, kinds
    events = [(log_ns, json.loads(data)) for log_ns, data in recorded_events(rec)]
    for e in out["messages"]["/pamd/sim/events"]:  # several may share a log time
        assert (int(e["log_ns"]), e["body"]) in events, e
    assert daemon.summary()["lost_records"] == 0


def test_a_stalled_viewer_never_holds_up_the_loop(tmp_path: Path) -> None:
    """A viewer that stops reading: the Foxglove server drops what it cannot send;
    the io process never waits, so with a ring of 1 s no tick record is lost, and a
    healthy viewer beside it keeps receiving to the end. (A viewer that held the io
    process up would fill any ring within the run's 8 s; 0.2 s lost records on a busy
    2-core PC, where the io process itself waited that long for a core.)"""
    port = free_port()
    cfg = rig_config(tmp_path, None, telemetry={"rate_hz": 500.0},
                     recording={"ring_s": 1.0})
    url = f"ws://127.0.0.1:{port}"
    topics = ",".join(TOPICS)
    stalled = Viewer(tmp_path, url, "--topics", topics, "--stall-after", "10", "--summary",
                     "--timeout", "120", "--connect-timeout", "60", name="stalled")
    healthy = Viewer(tmp_path, url, "--topics", topics, "--summary", "--timeout", "120",
                     "--connect-timeout", "60", name="healthy")
    daemon = DaemonProc(tmp_path, ["--config", str(cfg), "--record", str(tmp_path / "rec"),
                                   "--no-telemetry", "--foxglove", f"127.0.0.1:{port}", *SINE,
                                   "--duration", "8"])
    try:
        stalled.wait_receiving()
        healthy.wait_receiving()
        assert daemon.proc.wait(120) == 0, daemon.log()
        good = healthy.result()
    finally:
        stalled.kill()
        healthy.kill()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    summary = daemon.summary()
    assert summary["lost_records"] == 0 and summary["overruns"] >= 0
    assert summary["recording"]["ticks_recorded"] == summary["ticks"]
    assert summary["faults"] == []
    # the healthy viewer received to the end (within 2 s of the last tick)
    assert good["counts"]["/pamd/sim/state/m1"] > 0
    assert good["last"]["/pamd/sim/state/m1"]["tick"] >= summary["ticks"] - 1000, (
        good["last"], summary["ticks"])


def test_a_taken_foxglove_port_refuses_before_anything_moves(tmp_path: Path) -> None:
    with socket.socket() as holder:  # someone else has the port
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        cfg = rig_config(tmp_path, None, telemetry={"foxglove": {
            "enabled": True, "listen": f"127.0.0.1:{port}"}})
        r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config", str(cfg),
                            "--record", str(tmp_path / "rec"), "--no-telemetry",
                            "--duration", "5"], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0
    assert f"foxglove: cannot serve on 127.0.0.1:{port}" in r.stderr, r.stderr
    assert "in use" in r.stderr and "Traceback" not in r.stderr
    assert "STARTING" not in r.stderr and "safe outputs saved" not in r.stderr
    assert not (tmp_path / "rec").exists() or not any((tmp_path / "rec").iterdir())


def test_a_bad_listen_address_is_refused_with_its_field(tmp_path: Path) -> None:
    cfg = rig_config(tmp_path, None, telemetry={"foxglove": {"enabled": True,
                                                             "listen": "localhost"}})
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config", str(cfg),
                        "--no-telemetry", "--duration", "1"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode != 0 and "telemetry.foxglove.listen" in r.stderr, r.stderr
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--foxglove", "1.2.3.4:99999",
                        "--duration", "1"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--foxglove" in r.stderr and "HOST:PORT" in r.stderr


def test_a_restart_in_place_keeps_the_view() -> None:
    """A reload that reopens the devices execs `pamd run` again: the view stays on."""
    from pamd.client.cli.main import build_parser
    from pamd.daemon.service.restart import run_argv

    for given, kept in ((["--foxglove"], ["--foxglove", "default"]),
                        (["--foxglove", "0.0.0.0:9000"], ["--foxglove", "0.0.0.0:9000"]),
                        ([], [])):
        args = build_parser().parse_args(["run", "--no-telemetry", *given])
        argv = run_argv(args, remaining_s=None)
        assert argv[4:] == ["--no-telemetry", *kept]


@dataclass(frozen=True)
class Clock:  # a run's clock (pamd.wire.seams.RunClock), as the view reads it
    virtual: bool
    wall0_ns: int
    clock0_s: float
    rate_hz: float


def test_with_a_certificate_the_view_serves_wss_only(tmp_path: Path) -> None:
    """telemetry.foxglove.tls_cert and tls_key: the server (the foxglove-sdk's, given
    them) completes a TLS handshake that checks its certificate against the CA and
    upgrades to the Foxglove protocol; a plain ws:// request gets no upgrade."""
    import shutil
    import ssl

    import pytest

    from pamd.iohost.live import LiveView
    from pamd.iohost.viewer_spec import ViewerSpec

    if shutil.which("openssl") is None:
        pytest.fail("openssl is not installed (apt-get install openssl, or run "
                    ".ci/setup-tests)")
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt",
                    "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", "view.key", "-out",
                    "view.pem", "-days", "2", "-subj", "/CN=localhost", "-addext",
                    "subjectAltName=IP:127.0.0.1"], cwd=tmp_path, check=True,
                   capture_output=True, timeout=60)
    port = free_port()
    spec = ViewerSpec("127.0.0.1", port, "sim", ("m1",), 10,
                      tls_cert=(tmp_path / "view.pem").read_bytes(),
                      tls_key=(tmp_path / "view.key").read_bytes())
    clock = Clock(virtual=True, wall0_ns=0, clock0_s=0.0, rate_hz=1000.0)
    view = LiveView(spec, clock, lambda: None)
    assert view.open() is None and spec.url == f"wss://127.0.0.1:{port}"
    upgrade = (f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
               "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
               "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n"
               "\r\n").encode()
    try:
        ctx = ssl.create_default_context(cafile=str(tmp_path / "view.pem"))
        with socket.create_connection(("127.0.0.1", port), timeout=10) as sock, \
                ctx.wrap_socket(sock, server_hostname="127.0.0.1") as tls:
            tls.sendall(upgrade)
            assert tls.recv(200).startswith(b"HTTP/1.1 101 Switching Protocols")
        with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
            sock.sendall(upgrade)
            assert not sock.recv(200).startswith(b"HTTP/1.1 101")  # a TLS alert, or closed
    finally:
        view.close()

"""One simulated rig (`pamd run`, real clock, its own port, recording) and separate
client processes with their own Zenoh sessions: state, status, a setpoint the
pressure follows, every kind of bad command refused with nothing moved, a deadman,
the CLI clients, and at the end what the recording says about all of it."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest

from pamd.wire.record.files import Decoder, iter_messages

from .conftest import RigProc, pamd_cli, wait_until

RIG = "sim"


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RigProc]:
    # the flood limit is tested on its own (test_lifecycle); here, many commands at once
    r = RigProc(tmp_path_factory.mktemp("net"), RIG,
                telemetry={"command_rate_per_s": 1000.0, "command_burst": 200})
    yield r
    r.close()


def test_state_status_and_liveliness(rig: RigProc) -> None:
    assert rig.agent.call("rigs") == {"rigs": [RIG]}
    rig.agent.call("subscribe", name="state", key=f"pamd/{RIG}/state/m1")
    got = rig.agent.call("until", name="state", field="pressure_bar", seconds=30)
    assert got["met"], got
    sample = got["msg"]
    assert sample["tick"] >= 0 and sample["state"] in (1, 2)  # IDLE or RUNNING
    assert {"setpoint_bar", "valve_cmd_bar", "force_n", "length_mm", "flags"} <= set(sample)
    st = rig.status()
    assert st["ok"] and st["rig_id"] == RIG and st["state"] == "IDLE"
    m1 = st["muscles"]["m1"]
    assert m1["limits"]["max_pressure_bar"] == 6.0 and m1["datums"]["has_length_datum"]
    assert m1["referenced"] and m1["references"]["length_referenced"]  # deprecated, served
    assert m1["mode"] == "pressure" and m1["model"] is None and m1["profile"] is None
    assert m1["adapt"]["state"] == "off" and m1["adapt"]["why_not"] == "no model"
    assert len(st["config_sha256"]) == 64 and st["clock"] == "real" and st["rate_hz"] == 500
    assert st["timing"]["ticks"] > 0 and "p99" in st["timing"]["wake_latency_us"]
    assert "setpoint" in st["verbs"] and st["snapshot_age_s"] < 10


# verb, request, what the error must say (an estop or stop is never refused for its
# payload: it acts, the rest cut: tests/adversary/test_net_commands.py)
BAD: list[tuple[str, dict[str, Any], str]] = [
    ("setpoint", {"raw": "{not json"}, "malformed JSON"),
    ("setpoint", {"raw": "[1, 2]"}, "must be a JSON object"),
    ("fly", {"payload": {}}, "unknown command 'fly'"),
    ("setpoint", {"payload": {"bar": 2.0}}, "muscle: expected key 'muscle'"),
    ("setpoint", {"payload": {"muscle": "m1", "bar": 2.0, "speed": 3}}, "speed"),
    ("setpoint", {"payload": {"muscle": "m1", "bar": "high"}}, "bar: expected a number"),
    ("setpoint", {"payload": {"muscle": 7, "bar": 2.0}}, "muscle: expected text"),
    ("setpoint", {"payload": {"muscle": "m1", "bar": True}}, "bar: expected a number"),
    ("setpoint", {"raw": '{"muscle": "m1", "bar": NaN}'}, "finite"),
    ("setpoint", {"raw": '{"muscle": "m1", "bar": Infinity}'}, "finite"),
    ("setpoint", {"raw": '{"muscle": "m1", "bar": 1e999}'}, "finite"),
    ("setpoint", {"payload": {"muscle": "m1", "bar": 9.0}}, "outside 0-6 bar"),
    ("setpoint", {"payload": {"muscle": "m1", "bar": -1.0}}, "bar: expected a value at least 0"),
    ("setpoint", {"payload": {"muscle": "m9", "bar": 1.0}}, "no muscle named 'm9'"),
    ("setpoint", {"payload": {"muscle": "m1", "bar": 2.0, "ramp_s": 0.01}}, "slew limit"),
    ("setpoint", {"payload": {"muscle": "m1", "bar": 2.0, "deadman_s": 0}}, "deadman_s"),
    ("profile", {"payload": {"kind": "sine", "max_bar": 8.0}}, "outside 0-6 bar"),
    ("profile", {"payload": {"kind": "zigzag"}}, "unknown profile shape"),
    ("profile", {"payload": {"cycles": 1.5}}, "cycles: expected an integer"),
    ("load", {"payload": {"muscle": "m1", "load_kg": 500.0}}, "exceeds"),
    ("home", {"payload": {"muscle": "m1", "length_mm": -5.0}}, "greater than 0"),
    ("mode", {"payload": {"mode": "warp"}}, "mode"),
    ("hold", {"payload": {"x": 1}}, "x:"),
    ("resume", {"payload": {}}, "resume only from HOLD"),
    ("reset", {"payload": {}}, "nothing to reset"),
    ("confirm", {"payload": {}}, "no experiment is running"),
    ("pause", {"payload": {}}, "no experiment is running"),
    ("collect", {"payload": {"plan_file": "/nonexistent/plan.yaml"}}, "plan refused"),
    ("model", {"payload": {"muscle": "m1", "file": "/nonexistent/model.json"}}, "model"),
]


def test_every_bad_command_is_refused_and_nothing_moves(rig: RigProc) -> None:
    before = rig.status()
    assert before["state"] == "IDLE"
    sp0 = before["muscles"]["m1"]["setpoint_bar"]
    verdicts = rig.agent.call("cmds", rig=RIG, list=[
        {"verb": verb, **req} for verb, req, _ in BAD])
    for (verb, req, want), v in zip(BAD, verdicts, strict=True):
        assert v.get("ok") is False, (verb, req, v)
        assert want in v["error"], (verb, req, v)
    after = rig.status()
    assert after["state"] == "IDLE" and after["fault"] is None
    assert after["muscles"]["m1"]["setpoint_bar"] == sp0
    assert after["io"]["refused_here"] >= 19  # refused in the io process, not the loop


def test_setpoint_and_the_pressure_follows(rig: RigProc) -> None:
    rig.agent.call("subscribe", name="follow", key=f"pamd/{RIG}/state/m1")
    v = rig.cmd("setpoint", {"muscle": "m1", "bar": 3.0})
    assert v["ok"] and v["bar"] == 3.0 and v["muscle"] == "m1", v
    got = rig.agent.call("until", name="follow", field="setpoint_bar", above=2.9999, seconds=30)
    assert got["met"], got  # the ramp has reached the setpoint ...
    got = rig.agent.call("until", name="follow", field="pressure_bar", above=2.95, below=3.05,
                         seconds=30)
    assert got["met"] and got["msg"]["setpoint_bar"] == 3.0, got  # ... and the pressure
    st = wait_until(lambda: (s := rig.status())["muscles"]["m1"]["setpoint_bar"] == 3.0 and s,
                    30, "the status to show the setpoint")
    assert st["state"] == "RUNNING" and st["muscles"]["m1"]["profile"] == "ramp"


def test_streamed_setpoints_deadman_goes_to_the_safe_state(rig: RigProc) -> None:
    rig.agent.call("subscribe", name="ev", key=f"pamd/{RIG}/events")
    verdicts = rig.agent.call("stream", rig=RIG, muscle="m1", bar=2.0, deadman_s=1.0,
                              period_s=0.05, count=5)
    assert all(v["ok"] and v["deadman_s"] == 1.0 for v in verdicts), verdicts
    # no more refreshes: the loop goes to the safe state by itself
    got = rig.agent.call("until", name="ev", kind="deadman", seconds=30)
    assert got["met"] and got["msg"]["data"] == {"muscle": "m1", "timeout_s": 1.0}, got
    got = rig.agent.call("until", name="ev", kind="transition", contains="deadman", seconds=30)
    assert got["met"] and got["msg"]["data"]["to"] == "IDLE", got


def test_cli_clients(rig: RigProc) -> None:
    ep = rig.endpoint
    r = pamd_cli("status", "--connect", ep, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["rig_id"] == RIG
    r = pamd_cli("status", "--connect", ep)
    assert r.returncode == 0 and "rig sim (daemon of " in r.stdout and "m1:" in r.stdout, \
        r.stderr
    r = pamd_cli("cmd", "--connect", ep, "hold")
    assert r.returncode == 0 and json.loads(r.stdout)["ok"], r.stdout + r.stderr
    r = pamd_cli("cmd", "--connect", ep, "resume", "--user", "cli-tester")
    assert r.returncode == 0, r.stdout + r.stderr
    r = pamd_cli("cmd", "--connect", ep, "setpoint", "--muscle", "m1", "--bar", "99")
    assert r.returncode == 4 and "outside 0-6 bar" in r.stderr, r.stdout + r.stderr
    r = pamd_cli("cmd", "--connect", ep, "load", "--arg", "muscle=m1", "--arg", "load_kg=30")
    assert r.returncode == 0 and json.loads(r.stdout)["load_kg"] == 30, r.stdout + r.stderr
    r = pamd_cli("watch", "--connect", ep, "--duration", "1.5", "--plain")
    assert r.returncode == 0 and "m1" in r.stdout and "samples/s" in r.stdout, r.stderr
    r = pamd_cli("cmd", "--connect", ep, "--rig", "nosuch", "hold", "--timeout", "1")
    assert r.returncode == 7 and "no answer on pamd/nosuch/cmd/hold" in r.stderr, r.stderr


def test_stop_withdraws_and_the_recording_says_it_all(rig: RigProc) -> None:
    rc = rig.daemon.stop()
    assert rc == 0, rig.daemon.log()[-3000:]
    gone = rig.agent.call("rigs")  # none alive; or, its session closed with the daemon
    assert gone == {"rigs": []} or "cannot connect" in gone.get("no_daemon", ""), gone
    gone = rig.agent.call("status", rig=RIG, timeout=1.0)["no_daemon"]
    assert "no answer" in gone or "cannot connect" in gone
    summary = rig.daemon.summary()
    assert summary["telemetry"]["rig_id"] == RIG and summary["final_state"] == "IDLE"
    [path] = summary["recording"]["files"]
    dec = Decoder()
    events, setpoints = [], []
    for ch, schema, msg in iter_messages(path):
        if ch.topic.endswith("/events"):
            events.append(json.loads(msg.data))
        elif ch.topic == f"/pamd/{RIG}/state/m1":
            cols = dec.columns(ch, schema)
            row = dec.decode(ch, schema, msg.data)
            assert cols is not None and row is not None
            setpoints.append((msg.log_time, dict(zip(cols, row, strict=False))))
    cmds = [e["data"] for e in events if e["kind"] == "command"]
    sender = f"zenoh:{rig.zid}"
    # every bad command is in the recording, refused, with who sent it (those refused
    # like another in the same second counted by the next record of their kind)
    bad = [c for c in cmds if c["sender"] == sender and c["user"] == "tester"
           and c["ok"] is False]
    counted = sum(1 + c.get("refused_unrecorded", 0) for c in bad) + sum(
        e["data"]["refused_unrecorded"] for e in events if e["kind"] == "refusals")
    assert counted >= len(BAD)
    assert {c["verb"] for c in bad} >= {verb for verb, _r, _w in BAD}
    assert any(c.get("by") == "io" and "malformed JSON" in c["error"] for c in bad)
    # ... and the good ones, with their verdicts
    ok = [c for c in cmds if c["ok"] and c["sender"] == sender]
    assert any(c["verb"] == "setpoint" and c["bar"] == 3.0 for c in ok)
    assert any(c["verb"] == "resume" and c["user"] == "cli-tester" for c in cmds)
    # the valve did not move for them: while they came in the rig held its setpoint
    t_bad = [e["t_s"] for e in events if e["kind"] == "command"
             and e["data"].get("user") == "tester" and e["data"]["ok"] is False]
    assert t_bad
    window = [v for _t, v in setpoints if min(t_bad) <= v.get("t_s", -1) <= max(t_bad)]
    assert window and len({round(v["setpoint_bar"], 9) for v in window}) == 1

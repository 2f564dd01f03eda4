"""A virtual run recorded by the io process reads back, with the `mcap` package and
its ROS 2 decoder, exactly as the loop saw it: one message per muscle and one loop
message per tick, every field equal, events, metadata and attachments present."""

from __future__ import annotations

import json
import time
from typing import Any

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS, TickLayout

from .conftest import same


def read_all(path: str) -> dict[str, Any]:
    out: dict[str, Any] = {"msgs": {}, "meta": {}, "att": {}}
    with open(path, "rb") as fh:
        r = make_reader(fh, decoder_factories=[DecoderFactory()])
        out["summary"] = r.get_summary()
        decoders: dict[int, Any] = {}  # one ROS 2 decoder per schema, not per message
        for schema, ch, m in r.iter_messages():
            if ch.message_encoding == "cdr":
                if schema.id not in decoders:
                    decoders[schema.id] = DecoderFactory().decoder_for(ch.message_encoding,
                                                                       schema)
                body = decoders[schema.id](m.data)
            else:
                body = json.loads(m.data)
            out["msgs"].setdefault(ch.topic, []).append((m.log_time, body))
        out["meta"] = {m.name: dict(m.metadata) for m in r.iter_metadata()}
        out["att"] = {a.name: a.data for a in r.iter_attachments()}
    return out


def test_every_tick_recorded_with_every_field_as_the_loop_saw_it(recorded_run: Any) -> None:
    run = recorded_run(duration_s=2.0, profile={"kind": "sine", "min_bar": 1.0,
                                                "max_bar": 3.0, "freq_hz": 0.5})
    assert len(run.files) == 1
    rows = run.cap.rows
    n = len(rows)
    assert n == run.result["ticks"] and n > 2000
    assert run.result["lost_records"] == 0 and run.result["recording"]["lost_records"] == 0
    f = read_all(run.files[0])
    layout = TickLayout(["m1"])
    state = f["msgs"]["/pamd/sim/state/m1"]
    loop = f["msgs"]["/pamd/sim/loop"]
    assert len(state) == n and len(loop) == n  # exactly one message per tick, no loss
    wall0 = state[0][0]
    assert abs(wall0 - time.time_ns()) < 3600e9  # wall clock at the run's start
    for k, row in enumerate(rows):
        d = layout.as_dict(row)
        log_ns, msg = state[k]
        assert msg.tick == k and same(msg.t_s, row[1])
        assert log_ns == wall0 + k * 1_000_000  # virtual clock: start + tick x period
        for name in MUSCLE_FIELDS:
            assert same(float(getattr(msg, name)), d["m1"][name]), (k, name)
        lmsg = loop[k][1]
        for name in LOOP_FIELDS:
            assert same(float(getattr(lmsg, name)), d[name]), (k, name)
    # the profile really ran: the recorded setpoint rose from ~0 above 1 bar
    sps = [m.setpoint_bar for _t, m in state]
    assert max(sps) > 1.0 and min(sps) < 0.1


def test_events_metadata_and_attachments(recorded_run: Any) -> None:
    run = recorded_run(duration_s=0.5, profile={"kind": "sine", "min_bar": 1.0,
                                                "max_bar": 2.0, "freq_hz": 0.5})
    f = read_all(run.files[0])
    ev = [body for _t, body in f["msgs"]["/pamd/sim/events"]]
    kinds = [e["kind"] for e in ev]
    seen = [(k, d) for _t, k, d in run.cap.events]
    # every event the loop emitted is on the events topic, in order, with its data
    assert [(e["kind"], e["data"]) for e in ev] == [
        (k, json.loads(json.dumps(d, default=str))) for k, d in seen]
    assert "transition" in kinds and "command" in kinds
    tr = [e["data"] for e in ev if e["kind"] == "transition"]
    assert tr[0]["from"] == "STARTING" and tr[0]["to"] == "IDLE" and tr[0]["reason"]
    cmd = next(e["data"] for e in ev if e["kind"] == "command")
    assert cmd["verb"] == "profile" and cmd["ok"] is True and cmd["args"]["shape"] == "sine"
    meta = f["meta"]
    assert meta["pamd"]["note"] == "test note"
    assert meta["pamd"]["rig_id"] == "sim" and meta["pamd"]["clock"] == "virtual"
    assert meta["pamd"]["pamd_version"] and meta["pamd"]["host"]
    cfg = run.daemon.cfg
    assert json.loads(meta["pamd.config"]["resolved"])["rig_id"] == "sim"
    assert meta["pamd.config"]["sha256"] == cfg.sha256
    assert float(meta["pamd.loads"]["m1"]) == 30.0
    assert "file" in meta["pamd.calibration"]
    summ = meta["pamd.summary"]
    assert int(summ["ticks"]) == run.result["ticks"] and int(summ["lost_records"]) == 0
    assert summ["stop_reason"] == "duration reached"
    assert summ["io_stop"] == "stopped by the daemon"
    assert f["att"]["sim.yaml"].decode() == cfg.text
    st = f["summary"].statistics
    assert st.message_count == sum(len(v) for v in f["msgs"].values())


def test_two_muscles_each_get_their_channel(recorded_run: Any) -> None:
    sim_m = [{"name": n, "nominal_length_mm": 200, "load_kg": 30} for n in ("m1", "m2")]
    muscles = [{"name": n, "type": "dmsp20", "nominal_length_mm": 200, "load_kg": 30,
                "signals": {"pressure": {"driver": "sim", "channel": f"{n}.pressure"},
                            "force": {"driver": "sim", "channel": f"{n}.force"},
                            "length": {"driver": "sim", "channel": f"{n}.length"},
                            "valve": {"driver": "sim", "channel": f"{n}.valve",
                                      "raw_min": 0.0, "raw_max": 6.0}}}
               for n in ("m1", "m2")]
    run = recorded_run(duration_s=0.5, drivers=[{"name": "sim", "type": "sim",
                                                 "options": {"seed": 1, "muscles": sim_m}}],
                       muscles=muscles)
    f = read_all(run.files[0])
    layout = TickLayout(["m1", "m2"])
    for name in ("m1", "m2"):
        msgs = f["msgs"][f"/pamd/sim/state/{name}"]
        assert len(msgs) == len(run.cap.rows)
        for row, (_t, m) in zip(run.cap.rows, msgs, strict=True):
            d = layout.as_dict(row)[name]
            assert all(same(float(getattr(m, k)), d[k]) for k in MUSCLE_FIELDS)


def test_rotation_by_duration_splits_without_losing_a_tick(recorded_run: Any) -> None:
    run = recorded_run(duration_s=2.5, recording={"rotate_s": 1.0})
    files = run.files
    assert len(files) == 3
    ticks: list[int] = []
    for i, p in enumerate(files):
        f = read_all(p)
        assert f["meta"]["pamd"]["segment"] == str(i)
        ticks += [m.tick for _t, m in f["msgs"]["/pamd/sim/state/m1"]]
        assert f["att"]["sim.yaml"]
    assert ticks == list(range(len(run.cap.rows)))


def test_rotation_by_size(recorded_run: Any) -> None:
    run = recorded_run(duration_s=1.5, recording={"rotate_mb": 0.06})
    assert len(run.files) >= 2
    ticks: list[int] = []
    for p in run.files:
        f = read_all(p)
        ticks += [m.tick for _t, m in f["msgs"]["/pamd/sim/state/m1"]]
    assert ticks == list(range(len(run.cap.rows)))
    # every file but the last is cut at the first chunk past the size
    import os
    assert all(os.path.getsize(p) < 0.06e6 + 64_000 for p in run.files[:-1])


def test_markers_from_another_thread_reach_the_file(tmp_path: Any, sim_config: Any) -> None:
    """Events from any thread (an experiment runner, the CLI) are handed to the loop's
    thread, which alone writes the rings, and land on the events topic in order."""
    from pamd.daemon.daemon import Daemon
    from pamd.daemon.io_session import RecordingRequest

    d = Daemon(sim_config(30.0), recording=RecordingRequest(dir=str(tmp_path / "r")))
    d.start(None)
    try:
        for k in range(5):
            d.summary.event(d.ctrl.now, "marker", {"step": k, "load_kg": 10.0 * k})
            time.sleep(0.01)
    finally:
        d.stop("test finished")
        d.wait(60)
        d.close()
    f = read_all(d.result()["recording"]["files"][0])
    marks = [b["data"] for _t, b in f["msgs"]["/pamd/sim/events"] if b["kind"] == "marker"]
    assert marks == [{"step": k, "load_kg": 10.0 * k} for k in range(5)]

"""The command mailbox from the io process to the loop: a command sent on the io side
reaches the loop, is applied there, and its verdict comes back to the io side."""

from __future__ import annotations

import json
from types import SimpleNamespace
from typing import Any

from mcap.reader import make_reader

from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.iohost.process import RingCommandPort
from pamd.loop.io_link import RingMailbox
from pamd.wire.ring import BlockLayout, SharedBlock

from ..record.conftest import make_sim_config


class EventsOut:
    def __init__(self, block: SharedBlock) -> None:
        self.ring = block.events

    def event(self, t_s: float, kind: str, data: dict[str, Any]) -> None:
        assert self.ring.put_blob(json.dumps({"t": t_s, "kind": kind, "data": data}).encode())


def test_command_and_verdict_round_trip_through_the_rings() -> None:
    block = SharedBlock(BlockLayout(record_bytes=8, tick_slots=4), create=True)
    try:
        port = RingCommandPort(block)  # io side
        verdicts: list[dict[str, Any]] = []
        port.send("hold", {}, sender="zenoh", user="ana", on_verdict=verdicts.append)
        port.send("setpoint", {"muscle": "m1", "bar": "high"}, sender="zenoh",
                  on_verdict=verdicts.append)
        box = RingMailbox(SimpleNamespace(block=block), EventsOut(block), lambda: 1.5)
        cmd = box.poll()  # loop side
        assert cmd.verb == "hold" and cmd.sender == "zenoh" and cmd.user == "ana"
        cmd.reply({"ok": True})
        assert box.poll() is None  # malformed payload: refused in the loop, answered
        assert box.poll() is None
        while (blob := block.events.get_blob()) is not None:
            ev = json.loads(blob)
            assert ev["kind"] == "reply" and ev["t"] == 1.5
            port.on_reply(ev["data"])
        assert verdicts[0] == {"id": 1, "ok": True}
        assert verdicts[1]["id"] == 2 and verdicts[1]["ok"] is False
        assert "bar" in verdicts[1]["error"]
    finally:
        block.close()


def test_commands_from_the_io_process_reach_the_loop_and_verdicts_return(
        tmp_path: Any) -> None:
    script = ((20, "load", {"muscle": "m1", "load_kg": 20.0}),
              (30, "setpoint", {"muscle": "zz", "bar": 1.0}),
              (40, "nonsense", {}))
    d = Daemon(make_sim_config(tmp_path),
               recording=RecordingRequest(dir=str(tmp_path), script=script))
    d.start(1.0)
    d.wait(60)
    d.close()
    assert d.ctrl.muscles[0].load_kg == 20.0  # the io process's command was applied
    [path] = d.result()["recording"]["files"]
    with open(path, "rb") as fh:
        evs = [json.loads(m.data) for _s, _c, m in make_reader(fh).iter_messages(
            topics=["/pamd/sim/events"])]
    cmds = [e["data"] for e in evs if e["kind"] == "command"]
    assert [(c["verb"], c["sender"], c["ok"]) for c in cmds] == [
        ("load", "script", True), ("setpoint", "script", False)]
    back = {e["data"]["id"]: e["data"] for e in evs if e["kind"] == "verdict_received"}
    assert back[1]["ok"] is True and back[1]["load_kg"] == 20.0
    assert back[2]["ok"] is False and "no muscle named 'zz'" in back[2]["error"]
    assert back[3]["ok"] is False and "unknown command" in back[3]["error"]

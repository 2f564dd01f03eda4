"""Commands that cannot kill the daemon or read through it (issue 12, item 1): files
by name from a configured directory within size and nesting limits, text fields
capped at parse, recorded refusals cut to a head and a size, any failure in the loop
a refusal, and a burst taken a bounded number per tick."""

from __future__ import annotations

import json
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from pamd.loop.commands import Command, named_files, parse_command
from pamd.loop.loop import MAX_COMMANDS_PER_TICK
from pamd.wire.errors import CommandRefused
from pamd.wire.ring import BlockLayout
from pamd.wire.tick import State
from pamd.wire.verbs.args import MAX_TEXT_CHARS, args_for_record

SECRET = "-----BEGIN PRIVATE KEY-----\nMIIEsecretsecretsecret\n-----END PRIVATE KEY-----\n"


# -- files by name, within limits ------------------------------------------------------------
def test_only_a_plain_name_in_the_configured_directory_resolves(tmp_path: Path) -> None:
    (tmp_path / "plan.yaml").write_text("name: x\n")
    assert named_files.resolve("plan.yaml", str(tmp_path), "plan", "plans_dir") == str(
        tmp_path / "plan.yaml")
    for bad in ("/etc/shadow", "../plan.yaml", "a/b.yaml", ".hidden", "..", "", "x" * 300):
        with pytest.raises(CommandRefused, match="must be a file name in telemetry.plans_dir"):
            named_files.resolve(bad, str(tmp_path), "plan", "plans_dir")
    with pytest.raises(CommandRefused, match="remote plan files are off.*plans_dir"):
        named_files.resolve("plan.yaml", None, "plan", "plans_dir")


def test_binary_deep_and_large_files_are_refused_with_their_position(tmp_path: Path) -> None:
    (tmp_path / "bin").write_bytes(b"ok\nab\xff\xfe")
    with pytest.raises(CommandRefused, match=r"'bin' is not UTF-8 text \(byte 5, line 2, "
                                             r"column 3\)"):
        named_files.read_limited(str(tmp_path / "bin"), "bin", "plan", 1000)
    (tmp_path / "deep.json").write_text('{"a": "[[[[", "b":\n  ' + "[" * 100_000)
    with pytest.raises(CommandRefused, match="nested more than 64 levels deep at line 2, "
                                             "column 66"):
        named_files.read_limited(str(tmp_path / "deep.json"), "deep.json", "model", 1 << 20)
    (tmp_path / "big").write_text("x" * 1001)
    with pytest.raises(CommandRefused, match="1001 bytes, above the limit of 1000 bytes"):
        named_files.read_limited(str(tmp_path / "big"), "big", "plan", 1000)
    with pytest.raises(CommandRefused, match="not a regular file"):
        named_files.read_limited(str(tmp_path), "d", "plan", 1000)
    (tmp_path / "ok.yaml").write_text("# it's [fine\nsteps: [[1, 2], {a: '[x'}]\n")
    assert named_files.read_limited(str(tmp_path / "ok.yaml"), "ok.yaml", "plan", 1000).text


def test_a_refused_plan_names_file_line_and_key_but_never_its_contents(
        tmp_path: Path, sim_config: Any) -> None:
    from pamd.daemon.host.host import read_plan

    cfg = sim_config(telemetry={"plans_dir": str(tmp_path)})
    (tmp_path / "ca.key").write_text(SECRET)
    (tmp_path / "bad.yaml").write_text("name: quick\nmuscle: m1\nsteps:\n  - secret_key: "
                                       "MIIEsecret\n")
    for name in ("ca.key", "bad.yaml"):
        with pytest.raises(CommandRefused) as exc:
            read_plan(name, cfg)
        text = str(exc.value)
        assert text.startswith(f"collect: plan refused: {name}") and "MIIE" not in text, text
    assert "bad.yaml:4: steps[0].secret_key:" in text


# -- text caps, recorded refusals ------------------------------------------------------------
def test_an_estop_with_a_4100_character_reason_fits_the_rings() -> None:
    cmd = parse_command("estop", {"reason": "r" * 4100}, user="u" * 5000)
    assert cmd.args.reason.startswith("r" * MAX_TEXT_CHARS)
    assert cmd.args.reason.endswith("[3900 more characters cut]") and len(cmd.user) < 100
    layout = BlockLayout(record_bytes=8, tick_slots=64)
    blob = json.dumps({"id": 1, "verb": "estop", "payload": vars(cmd.args), "sender": "s",
                       "user": cmd.user}).encode()
    assert len(blob) < layout.command_slot_bytes - 4  # was 4221 bytes: refused


def test_a_recorded_refusal_keeps_the_head_and_the_size() -> None:
    big = {"muscle": "m1", "pad": "x" * 1_000_000}
    rec = args_for_record(big)
    assert rec["bytes"] > 1_000_000 and len(rec["head"]) == 256
    assert rec["head"].startswith('{"muscle": "m1"')
    assert args_for_record({"muscle": "m1"}) == {"muscle": "m1"}
    assert args_for_record(b"\xff" * 10) == {"raw": "\ufffd" * 10}


# -- nothing a command does ends the loop ----------------------------------------------------
def test_a_handler_that_raises_is_a_recorded_refusal(sim_daemon: Any) -> None:
    d = sim_daemon()
    assert d.wait_for_state((State.IDLE,), timeout_s=30) == State.IDLE
    events: list[dict[str, Any]] = []
    d.summary.downstream.append(type("Cap", (), {
        "put": lambda self, r: True, "close": lambda self: None,
        "event": lambda self, t, k, data: events.append(data)})())
    got: list[dict[str, Any]] = []
    d.mailbox.put(Command("setpoint", object(), got.append))  # args no handler expects
    d.mailbox.put(Command("warp", object(), got.append))
    d.mailbox.put(Command("reset", object(), lambda v: 1 / 0))  # a reply that raises
    assert d.command("reset")["ok"] is False  # the loop still answers
    assert len(got) == 2 and not got[0]["ok"] and not got[1]["ok"]
    assert "setpoint failed in the loop (AttributeError" in got[0]["error"]
    assert "unknown command 'warp'" in got[1]["error"]
    assert any(e.get("verb") == "setpoint" and not e.get("ok") for e in events)
    assert d.alive and d.loop.command_faults == 1
    d.service()


def test_a_burst_is_taken_a_bounded_number_per_tick_and_each_gets_its_verdict(
        sim_daemon: Any) -> None:
    d = sim_daemon(loop={"clock": "virtual"})
    assert d.wait_for_state((State.IDLE,), timeout_s=30) == State.IDLE
    got: list[tuple[int, dict[str, Any]]] = []
    for i in range(200):
        d.mailbox.put(parse_command("setpoint", {"muscle": "m1", "bar": 1.0 + 0.5 * (i % 2)},
                                    reply=lambda v: got.append((d.ctrl.tick_no, v))))
    deadline = time.monotonic() + 60
    while len(got) < 200 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert len(got) == 200 and all(v["ok"] for _t, v in got), got[:3]
    per_tick = Counter(t for t, _v in got)
    assert max(per_tick.values()) <= MAX_COMMANDS_PER_TICK and len(per_tick) >= 50

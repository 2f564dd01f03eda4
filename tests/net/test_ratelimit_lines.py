"""One line per pattern per interval, the next saying how many were dropped
(`pamd.iohost.ratelimit`): what clients send cannot grow a log. And what an estop or stop
keeps of a payload it cannot take whole (`pamd.iohost.intake.salvage`)."""

from __future__ import annotations

import io
import json
import logging
from typing import Any

import pytest

from pamd.iohost import ratelimit
from pamd.iohost.intake import salvage
from pamd.iohost.ratelimit import LineLimiter, RateLimitedHandler, pattern_of


def test_one_line_per_pattern_per_interval_then_the_count() -> None:
    lim = LineLimiter(interval_s=10.0, max_patterns=3)
    assert lim.admit("a", 0.0) == 0
    assert [lim.admit("a", t) for t in (1.0, 2.0, 9.9)] == [None, None, None]
    assert lim.admit("b", 5.0) == 0  # another pattern is not held back
    assert lim.admit("a", 10.0) == 3  # the next says how many were dropped
    assert lim.due(25.0) == []  # nothing dropped since
    assert lim.admit("a", 21.0) == 0 and lim.admit("a", 22.0) is None
    assert lim.due(30.0) == [] and lim.due(31.0) == [("a", 1)]  # the end of a flood, said
    for k in "cdefgh":  # patterns are bounded: new ones share one
        lim.admit(k, 40.0)
    assert len(lim.last) <= 4 and ratelimit.OTHER_PATTERN in lim.last


def test_numbers_do_not_make_patterns() -> None:
    assert pattern_of("Invalid message from 127.0.0.1:55714: opcode 153") == \
        pattern_of("Invalid message from 10.0.0.7:1: opcode 9")


def test_the_handler_writes_a_flood_of_bad_frames_as_a_few_lines(
        monkeypatch: pytest.MonkeyPatch) -> None:
    clock = [0.0]
    monkeypatch.setattr(ratelimit.time, "monotonic", lambda: clock[0])
    out = io.StringIO()
    log = logging.getLogger("pamd-test-flood")
    h = RateLimitedHandler("pamd: foxglove: ", 10.0, out)
    log.addHandler(h)
    log.propagate = False
    try:
        for i in range(10_000):  # 100 s of 100 bad frames a second
            clock[0] = i / 100
            log.warning("Invalid message from 127.0.0.1:%d: expected value at line 1", i)
            log.warning("Client 127.0.0.1:%d attempted to subscribe to unknown channel: %d",
                        i, i)
        h.flush_due(200.0)
    finally:
        log.removeHandler(h)
    lines = out.getvalue().splitlines()
    assert 2 * 10 <= len(lines) <= 2 * 11 + 2, len(lines)  # 2 patterns, one per 10 s each
    assert len(out.getvalue()) < 5000  # was one line a frame: some 1.5 MB
    assert "(999 more like it in the last 10 s not shown)" in lines[2]
    assert lines[-1].endswith("in the last 10 s not shown")


def big(**fields: Any) -> bytes:
    return json.dumps(fields).encode()


def test_salvage_keeps_the_declared_fields_and_says_what_it_cut() -> None:
    assert salvage("estop", big(reason="hand in")) == ({"reason": "hand in"}, "")
    p, note = salvage("estop", big(reason="x" * 100_000, muscle="m1"))
    assert "reason cut from 100000" in note and "fields dropped: muscle" in note
    assert len(p["reason"]) <= 200 and p["reason"].endswith(f"[pamd: {note}]")
    p, note = salvage("estop", big(reason=12))  # mistyped: dropped, the default said
    assert p["reason"].startswith("emergency stop") and "reason" in note
    assert salvage("stop", big(x=1)) == ({}, "fields dropped: x")
    p, note = salvage("estop", b'{"reason": "stuck \\"valve\\"", "pad": "' + b"p" * (2 << 20))
    assert p["reason"].startswith('stuck "valve"') and "read in part" in note
    assert salvage("estop", b"")[0] == {}


def test_the_daemons_own_endpoint_bounds_what_clients_cost() -> None:
    """Sessions, message size and no shared-memory pool (pamd.wire.zconf): what 50
    clients cost the io process is bounded and comes back (tests/adversary)."""
    from pamd.wire import zconf

    cfg = zconf.daemon_config(None)
    assert zconf.get(cfg, "transport/unicast/max_sessions") == zconf.MAX_SESSIONS == 100
    assert zconf.get(cfg, "transport/link/rx/max_message_size") == 4 << 20
    assert zconf.get(cfg, "transport/shared_memory/enabled") is False
    assert zconf.get(cfg, "scouting/multicast/enabled") is False

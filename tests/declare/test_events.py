"""The event registry (pamd.wire.declare.events) declares every event kind pamd emits and
each payload's keys: a scan of every emission site in the source finds a kind not
declared or a literal payload key that drifted from its declaration; the recording's
event JSON schema and the docs derive from it. (tests/record/test_declared.py checks
the events of a real recorded run against it too.)"""

from __future__ import annotations

import ast
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from pamd.iohost import recorder
from pamd.wire.declare import events
from pamd.wire.declare.jsonsafe import dumps, jsonsafe

ROOT = Path(__file__).resolve().parents[2]

#: callables that take (t, kind, data) and those that take (kind, data)
KIND_SECOND = {"event"}
KIND_FIRST = {"_publish_event", "_record_io", "record"}
#: wrappers whose callers name a sub-kind: the kind they emit, and the key it goes in
WRAPPERS = {("loop/experiment/sequencer.py", "_event"): "experiment",
            ("daemon/host/collections.py", "_event"): "collection"}


def _sites() -> Iterator[tuple[str, int, str, ast.expr | None]]:
    """(file, line, kind, payload expression) of every call emitting a literal kind."""
    for path in sorted((ROOT / "pamd").rglob("*.py")):
        rel = str(path.relative_to(ROOT / "pamd"))
        if rel.startswith("declare/"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Call) or not isinstance(node.func, ast.Attribute):
                continue
            name, args = node.func.attr, node.args
            if (rel, name) in WRAPPERS:
                yield rel, node.lineno, WRAPPERS[(rel, name)], None
                continue
            pos = 1 if name in KIND_SECOND else 0 if name in KIND_FIRST else None
            if pos is None or len(args) <= pos:
                continue
            kind = args[pos]
            if isinstance(kind, ast.Constant) and isinstance(kind.value, str):
                data = args[pos + 1] if len(args) > pos + 1 else None
                yield rel, node.lineno, kind.value, data
            elif isinstance(kind, ast.IfExp):  # "a" if c else "b"
                for k in (kind.body, kind.orelse):
                    if isinstance(k, ast.Constant) and isinstance(k.value, str):
                        yield rel, node.lineno, k.value, None


def test_the_scan_finds_the_emission_sites() -> None:
    kinds = {k for _, _, k, _ in _sites()}
    # one of each emitter: the controller, the loop, the sequencer, the io process
    assert {"transition", "stall", "segment", "experiment", "command", "lost_records",
            "verdict_received", "run_start", "refusals"} <= kinds


def test_every_emitted_kind_is_declared_and_its_literal_payload_matches() -> None:
    wrong = []
    for rel, line, kind, data in _sites():
        k = events.EVENTS.get(kind)
        if k is None:
            wrong.append(f"pamd/{rel}:{line}: event {kind!r} is not declared in "
                         "pamd.wire.declare.events")
            continue
        if not isinstance(data, ast.Dict):
            continue  # built elsewhere: checked at run time (tests/record/test_declared.py)
        keys = {d.value for d in data.keys
                if isinstance(d, ast.Constant) and isinstance(d.value, str)}
        spread = any(d is None for d in data.keys)
        declared = {p.name for p in k.payload}
        extra = sorted(keys - declared) if not k.open else []
        missing = [] if spread else sorted(
            p.name for p in k.payload if p.required and p.name not in keys)
        if extra or missing:
            wrong.append(f"pamd/{rel}:{line}: {kind}: keys not declared {extra}, "
                         f"declared keys missing {missing}")
    assert not wrong, "\n".join(wrong)


def test_every_declared_kind_is_said_somewhere() -> None:
    """No declaration outlives its event: each kind's name is in pamd's source."""
    text = "\n".join(p.read_text() for p in (ROOT / "pamd").rglob("*.py")
                     if "declare" not in p.parts)
    dead = [k.name for k in events.DECLARED if f'"{k.name}"' not in text]
    assert not dead


def test_problems_names_what_drifted() -> None:
    ok = {"from": "IDLE", "to": "RUNNING", "reason": "profile"}
    assert events.problems("transition", ok) == []
    assert events.problems("transition", {"from": "IDLE", "reason": "x"}) == [
        "transition: 'to' missing"]
    assert events.problems("transition", {**ok, "extra": 1}) == [
        "transition: 'extra' is not declared"]
    assert events.problems("stall", {"gap_ms": 12.0, "count": "1", "fault": False,
                                     "fault_ms": 500.0}) == [
        "stall: 'count' is str, declared integer"]
    assert events.problems("no_such", {}) == [
        "event 'no_such' is not declared in pamd.wire.declare.events"]
    # an open kind takes more keys (a verdict's), a closed one does not
    assert events.problems("reply", {"id": 3, "ok": True, "ramp_s": 1.5}) == []
    assert events.problems("reply", {"id": 3}) == ["reply: 'ok' missing"]


def _valid(event: dict[str, object]) -> bool:
    try:
        jsonschema.validate(event, recorder.EVENT_SCHEMA)
    except jsonschema.ValidationError:
        return False
    return True


def test_the_recorded_event_schema_is_the_registry() -> None:
    schema = recorder.EVENT_SCHEMA
    jsonschema.Draft202012Validator.check_schema(schema)
    recorded = [k.name for k in events.DECLARED if k.recorded]
    assert schema["properties"]["kind"]["enum"] == recorded  # type: ignore[index]
    assert {"startup", "soft_limit", "implausible", "deadman", "adapt",
            "verdict_received"} <= set(recorded)  # the six the old schema did not name
    base = {"t_s": 1.0, "tick": 1000}
    assert _valid({**base, "kind": "deadman", "data": {"muscle": "m1", "timeout_s": 0.5}})
    assert not _valid({**base, "kind": "deadman", "data": {"muscle": "m1"}})
    assert not _valid({**base, "kind": "deadman",
                       "data": {"muscle": "m1", "timeout_s": 0.5, "x": 1}})
    assert not _valid({**base, "kind": "run_start", "data": {}})  # Zenoh only
    # NaN is recorded as null: a number key takes it
    assert _valid(json.loads(dumps({**base, "kind": "supply", "data": {
        "state": "out", "supply_bar": float("nan"), "safety_chain": 1.0}})))


@pytest.mark.parametrize("kind", [k.name for k in events.DECLARED])
def test_every_kind_is_documented(kind: str) -> None:
    k = events.EVENTS[kind]
    assert k.meaning and k.emitted_by
    assert all(p.description and set(p.types) <= set(events.JSON_TYPES) for p in k.payload)


def test_one_json_encoder() -> None:
    from pamd.wire import status
    assert status.jsonsafe is jsonsafe  # the status snapshot's and the recording's
    x = {"a": float("nan"), 1: (float("inf"), 2.5, [float("-inf")]), "s": "t"}
    assert jsonsafe(x) == {"a": None, "1": [None, 2.5, [None]], "s": "t"}
    assert dumps(x) == '{"a":null,"1":[null,2.5,[null]],"s":"t"}'
    assert json.loads(dumps({"p": Path("/x")})) == {"p": "/x"}  # odd values: their text


def test_a_run_of_the_controller_says_only_declared_events_and_verdicts(harness: Any) -> None:
    """The tick stepped by hand: start-up, commands done and refused, a deadman, an ESTOP
    and its reset; every event the controller emits and every verdict it gives is as
    declared (the payloads built away from the emission sites are checked here)."""
    h = harness()
    h.step(0.1)
    verdicts = [h.cmd("setpoint", muscle="m1", bar=2.0, deadman_s=0.2),
                h.cmd("setpoint", muscle="m1", bar=99.0),  # refused: over the limit
                h.cmd("mode", muscle="m1", mode="position")]  # refused: no length datum
    h.step(0.5)  # the deadman fires
    verdicts += [h.cmd("estop", reason="test"), h.cmd("hold"), h.cmd("reset")]
    h.step(0.1)
    assert [v["ok"] for v in verdicts] == [True, False, False, True, False, True]
    kinds = {k for _, k, _ in h.sink.events}
    assert {"startup", "transition", "command", "deadman"} <= kinds
    wrong = [(k, p) for _, k, d in h.sink.events if (p := events.problems(k, json.loads(
        dumps(d))))]
    assert not wrong
    for i, v in enumerate(verdicts):
        assert events.problems("reply", {"id": i, **json.loads(dumps(v))}) == [], v

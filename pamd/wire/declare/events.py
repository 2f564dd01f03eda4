"""The event registry: every event pamd says, declared once by its name, and the verdict
a command gets.

An event is `(t_s, name, data)` (its name's key in the record is `kind`): the loop,
the daemon's main thread and the io process emit them; the recording writes them to
`/pamd/<rig>/events` (JSON, schema: `json_schema()`), Zenoh publishes them on
`<rig>/events`, exports write them as rows. Each `EventSpec` says what the event
means, who emits it and its payload's keys with JSON type, unit and meaning; `open`
events also carry keys that depend on something else (a command's verdict, a run's
summary), said in `extra`. `problems(name, data)` checks one event against its
declaration (tests run it over every event of a run and over every emission site in
the source).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: JSON types a payload key may have (JSON Schema's names)
JSON_TYPES = ("string", "number", "integer", "boolean", "array", "object", "null")


@dataclass(frozen=True)
class Key:
    """One key of an event's payload."""

    name: str
    type: str | tuple[str, ...]  # JSON type(s); "number" also takes null (NaN: no value)
    description: str
    unit: str = ""
    required: bool = True

    @property
    def types(self) -> tuple[str, ...]:
        return self.type if isinstance(self.type, tuple) else (self.type,)


def opt(name: str, type: str | tuple[str, ...], description: str, unit: str = "") -> Key:
    """A key present only on some events of the name."""
    return Key(name, type, description, unit, required=False)


@dataclass(frozen=True)
class EventSpec:
    """One event, declared: its name (the recorded `kind`), meaning, emitter, payload."""

    name: str
    meaning: str
    emitted_by: str
    payload: tuple[Key, ...]
    extra: str = ""  # "" closed: no other keys; else what the other keys are
    recorded: bool = True  # written to the recording (False: published on Zenoh only)

    @property
    def open(self) -> bool:
        return bool(self.extra)


#: the verdict a command gets (the reply to its sender, and inside its `command` event)
VERDICT: tuple[Key, ...] = (
    Key("ok", "boolean", "true: done (or begun) as asked; false: refused, nothing changed"),
    opt("error", "string", "why it was refused and what to do next (ok false)"),
    opt("rig", "string", "the rig whose io process refused it before the loop saw it"),
    opt("credential", "string", "why a command's signature was not taken (none, clear, "
        "stale, bad, replay: pamd.wire.credential)"),
    opt("command_nonce", "string", "this run's nonce, with a refusal of a command signed "
        "for another run (the client signs again with it: pamd.wire.credential)"),
)
VERDICT_EXTRA = "an accepted command's handler adds what it did (verb-specific keys)"

_MUSCLE = Key("muscle", "string", "the muscle's name")
_REASON = Key("reason", "string", "why, in words for the operator")
_BAR = "bar"
_COMMAND = (
    Key("verb", "string", "the command"),
    Key("args", "object", "its arguments as recorded (capped)"),
    Key("sender", "string", "who sent it (client name, script, io)"),
    opt("user", "string", "the sender's user"),
    opt("by", "string", "who refused it before the loop: daemon or io"),
)

DECLARED: tuple[EventSpec, ...] = (
    EventSpec("transition", "the supervisor changed state", "controller", (
        Key("from", "string", "the state left (pamd.wire.declare.fields.State)"),
        Key("to", "string", "the state entered"),
        _REASON)),
    EventSpec("startup", "the first readings taken: each muscle holds its measured pressure "
              "or ramps to its safe pressure", "controller", (
                  _MUSCLE,
                  Key("action", "string", "hold or safe_ramp"),
                  Key("pressure_bar", "number", "the pressure held or ramped from", _BAR),
                  opt("reason", "string", "why it ramps (outside its limits)"),
                  opt("safe_pressure_bar", "number", "where it ramps to", _BAR))),
    EventSpec("supply", "the supply pressure went out or came back", "controller", (
        Key("state", "string", "out or back"),
        Key("supply_bar", "number", "the supply reading (a switch: 0/1)", _BAR),
        Key("safety_chain", "number", "the chain: 1 closed, 0 open, null no input"))),
    EventSpec("safety_chain", "the hardware safety chain opened: ESTOP", "controller", (
        Key("state", "string", "open"), _REASON)),
    EventSpec("reset", "the reset button acknowledged a latched FAULT or ESTOP",
              "controller", (
                  Key("by", "string", "input (the button)"),
                  Key("ok", "boolean", "whether the latch was cleared"),
                  Key("reason", ("string", "null"), "why not, or the state's reason"))),
    EventSpec("implausible", "a reading is no longer trusted (plausibility on physics)",
              "controller", (
                  _MUSCLE, _REASON,
                  Key("trusted", "array", "the signals still trusted: pressure, force, "
                      "length"))),
    EventSpec("soft_limit", "a profile is held at a soft limit for more than a second",
              "controller", (
                  _MUSCLE,
                  Key("limit", "string", "which limit (pressure, contraction, pretension)"),
                  Key("held_s", "number", "how long it was held before this event", "s"),
                  Key("setpoint_bar", "number", "the setpoint", _BAR),
                  Key("valve_cmd_bar", "number", "the command after the limit", _BAR),
                  _REASON)),
    EventSpec("deadman", "no setpoint for a muscle within its deadman time: safe state",
              "controller", (
                  _MUSCLE,
                  Key("timeout_s", "number", "the deadman time", "s"))),
    EventSpec("adapt", "the model's online adaptation froze or hit its rate bound",
              "controller (pamd.loop.control.adapt)", (
                  _MUSCLE,
                  Key("action", "string", "frozen or rate_bound"),
                  _REASON,
                  Key("drift_bar", "number", "adapted minus trained output", _BAR),
                  Key("total_bar", "number", "the adapted model's output", _BAR),
                  opt("pressure_bar", "number", "the pressure of the refused sample",
                      _BAR))),
    EventSpec("feedforward", "the model's inputs left its training domain (said once a "
              "mode or model), or its feedforward began to oscillate against the pressure "
              "loop (once an episode)", "controller (pamd.loop.control.off_data)", (
                  _MUSCLE,
                  Key("what", "string", "off_data or oscillating"),
                  Key("action", "string", "fade (to the position PID alone) or warn"),
                  Key("inputs", "array", "the inputs outside the domain (pressure_bar: the "
                      "model's output); force_n for an oscillation"),
                  Key("values", "object", "their values at the tick that left it"),
                  opt("amplitude_bar", "number", "half the feedforward's swing so far", _BAR),
                  _REASON)),
    EventSpec("stall", "the loop's thread woke a period or more late", "loop", (
        Key("gap_ms", "number", "how long it was away", "ms"),
        Key("count", "integer", "stalls since start"),
        Key("fault", "boolean", "whether it was past the fault limit (FAULT latched)"),
        Key("fault_ms", "number", "the fault limit (loop.stall_fault_s)", "ms"))),
    EventSpec("segment", "an experiment step begins (a new recording file)",
              "experiment sequencer", (
                  Key("plan", "string", "the plan's name"),
                  Key("step", "string", "the step's name"),
                  Key("index", "integer", "the step's index, 0-based"),
                  Key("steps", "integer", "steps in the plan"),
                  _MUSCLE,
                  Key("load_kg", "number", "the step's hanging load", "kg"))),
    EventSpec("experiment", "a plan's progress: step_started, operator_action, cycle, "
              "step_finished, plan_finished, plan_ended", "experiment sequencer", (
                  Key("plan", "string", "the plan's name"),
                  Key("what", "string", "what happened"),
                  Key("step", ("string", "null"), "the step's name"),
                  Key("index", "integer", "the step's index, 0-based"),
                  Key("phase", "string", "the sequencer's phase"),
                  opt("prompt", "string", "what the operator is asked (operator_action)"),
                  opt("cycle", "integer", "the profile's cycle (cycle)"),
                  opt("outcome", "string", "how the plan ended (plan_finished, plan_ended)"))),
    EventSpec("command", "a command and its verdict (refused before or by the loop, or done)",
              "loop (pamd.loop.commands.apply), daemon, io process", (
                  *_COMMAND, *VERDICT,
                  opt("refused_unrecorded", "integer", "refusals like it not recorded "
                      "since the last recorded one (a flood)")),
              extra=VERDICT_EXTRA),
    EventSpec("command_cut", "an estop or stop honoured with part of its payload cut",
              "io process", (
                  *_COMMAND[:4],
                  Key("note", "string", "what was cut"),
                  opt("cut_unrecorded", "integer", "cuts like it not recorded"))),
    EventSpec("refusals", "the rest of a flood of refusals, counted", "io process", (
        Key("kind", "string", "the refusals' cause: rate, size, json, credential, pattern, "
            "or the refusal's text with its numbers as #"),
        Key("refused_unrecorded", "integer", "how many were not recorded one by one"),
        Key("rig", "string", "the rig"))),
    EventSpec("reply", "a verdict on its way back to the io process", "loop (command ring)",
              (Key("id", "integer", "the command's id"), *VERDICT), extra=VERDICT_EXTRA),
    EventSpec("verdict_received", "a scripted command's verdict came back to the io process",
              "io process", (Key("by", "string", "io process"), *VERDICT),
              extra=VERDICT_EXTRA),
    EventSpec("collection", "a collection started over the network: begun, started, closed, "
              "ended, dropped", "recorder, daemon (pamd.daemon.host.collections)", (
                  Key("what", "string", "what happened"),
                  Key("id", ("string", "integer"), "the collection's id"),
                  opt("dir", "string", "its directory"),
                  opt("files", ("integer", "array"), "its files (count, or names)"),
                  opt("ticks", "integer", "ticks it recorded"),
                  opt("outcome", "string", "how it ended")),
              extra="the collection's description (collection, manifest, resumed, "
                    "start_step, plan, sender, user)"),
    EventSpec("lost_records", "tick records lost to a full io ring", "io link", (
        Key("count", "integer", "records lost this time"),
        Key("first_tick", "integer", "the first lost tick"),
        Key("last_tick", "integer", "the last lost tick"),
        Key("total", "integer", "records lost since start"),
        opt("ongoing", "boolean", "the ring is still full: said after each second of a loss "
            "that goes on, not only when it ends"))),
    EventSpec("recording", "the recording stopped or failed; control goes on or stops as "
              "recording.on_failure says", "recorder, io session", (
                  Key("message", "string", "what happened, for the operator"),
                  opt("max_mb", "number", "the size cap reached", "MB"),
                  opt("what", "string", "what failed"),
                  opt("reason", "string", "why"),
                  opt("policy", "string", "recording.on_failure"),
                  opt("tick", "integer", "the tick it happened at"))),
    EventSpec("summary", "the run's summary, its last event", "daemon", (),
              extra="the run summary's keys (pamd.summary)"),
    EventSpec("run_start", "the io process's Zenoh node is up", "io process (Zenoh only)", (
        Key("rig_id", "string", "the rig"),
        Key("zid", "string", "the Zenoh session's id"),
        Key("muscles", "array", "the muscles' names")), recorded=False),
    EventSpec("run_stop", "the run ended (the summary, published)", "io process (Zenoh only)",
              (), extra="the run summary's keys", recorded=False),
)

EVENTS: dict[str, EventSpec] = {k.name: k for k in DECLARED}


def _is(value: object, t: str) -> bool:
    if t == "null":
        return value is None
    if t == "boolean":
        return isinstance(value, bool)
    if t == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if t == "number":  # NaN (no value) is recorded as null
        return (isinstance(value, (int, float)) and not isinstance(value, bool)) \
            or value is None
    if t == "string":
        return isinstance(value, str)
    if t == "array":
        return isinstance(value, (list, tuple))
    return isinstance(value, dict)


def problems(name: str, data: object) -> list[str]:
    """What is wrong with event `(name, data)` against its declaration ([] nothing)."""
    k = EVENTS.get(name)
    if k is None:
        return [f"event {name!r} is not declared in pamd.wire.declare.events"]
    if not isinstance(data, dict):
        return [f"{name}: the payload is not an object"]
    out = []
    keys = {p.name: p for p in k.payload}
    for p in k.payload:
        if p.required and p.name not in data:
            out.append(f"{name}: {p.name!r} missing")
    for given, value in data.items():
        key = keys.get(given)
        if key is None:
            if not k.open:
                out.append(f"{name}: {given!r} is not declared")
        elif not any(_is(value, t) for t in key.types):
            bad = "NaN" if isinstance(value, float) and math.isnan(value) else \
                type(value).__name__
            out.append(f"{name}: {given!r} is {bad}, declared {'/'.join(key.types)}")
    return out


def _key_schema(p: Key) -> dict[str, object]:
    types = list(p.types)
    if "number" in types and "null" not in types:
        types.append("null")
    out: dict[str, object] = {"type": types[0] if len(types) == 1 else types,
                              "description": p.description + (f", {p.unit}" if p.unit
                                                              else "")}
    return out


def payload_schema(k: EventSpec) -> dict[str, object]:
    return {"type": "object", "description": k.meaning,
            "properties": {p.name: _key_schema(p) for p in k.payload},
            "required": [p.name for p in k.payload if p.required],
            "additionalProperties": k.open}


def json_schema() -> dict[str, object]:
    """The JSON schema of a recorded event (`/pamd/<rig>/events`): `kind` (the
    event's name, the record's key for it) one of the recorded events, `data` that
    event's payload (JSON Schema if/then per name)."""
    recorded = [k for k in DECLARED if k.recorded]
    return {
        "title": "pamd event",
        "type": "object",
        "properties": {
            "t_s": {"type": "number", "description": "loop time since the run start, s"},
            "tick": {"type": "integer", "description": "tick number of the loop"},
            "kind": {"type": "string", "enum": [k.name for k in recorded],
                     "description": "the event's name (pamd.wire.declare.events): " +
                     ", ".join(k.name for k in recorded)},
            "data": {"type": "object", "description": "the event's payload"},
        },
        "required": ["t_s", "tick", "kind", "data"],
        "allOf": [{"if": {"properties": {"kind": {"const": k.name}}},
                   "then": {"properties": {"data": payload_schema(k)}}} for k in recorded],
    }

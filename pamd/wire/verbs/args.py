"""Commands' argument schemas (the dataclasses a payload is built into, checked and
capped), the `Command` on its way to the loop, and the caps on text.

Parsing is `pamd.wire.verbs.table`; which verb takes which schema is its declaration
(`pamd.wire.verbs.table.VERBS`). Nothing here needs the loop's state: the io process
imports it without the controller.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.schema.engine import spec
from pamd.wire.shape_names import shapes_reading, shapes_text


@dataclass(frozen=True, kw_only=True)
class SetpointArgs:
    muscle: str = spec(doc="Muscle name.")
    bar: float | None = spec(None, "Pressure setpoint (pressure mode).", unit="bar", min=0.0)
    length_mm: float | None = spec(None, "Length target (length_force and position modes).",
                                   unit="mm", gt=0.0)
    force_n: float | None = spec(None, "Force target (length_force mode; default: the force "
                                 "at the mode change).", unit="N", min=0.0)
    ramp_s: float | None = spec(None, "Reach the setpoint over this time (default: at half "
                                "the slew limit, or half control.position.max_rate_per_s "
                                "for a length).", unit="s", min=0.0)
    deadman_s: float | None = spec(None, "Streamed setpoints: unless the next setpoint for "
                                   "this muscle arrives within this time, the rig goes to "
                                   "the safe state (a later setpoint without it disarms "
                                   "it).", unit="s", gt=0.0)


@dataclass(frozen=True, kw_only=True)
class ProfileArgs:
    muscle: str | None = spec(None, "Muscle name (default: every muscle).")
    shape: str = spec("sine", f"Profile shape: {shapes_text()}.", old="kind")
    min_bar: float = spec(0.0, "Lowest pressure.", unit="bar", min=0.0)
    max_bar: float = spec(6.0, "Highest pressure.", unit="bar", min=0.0)
    freq_hz: float = spec(0.05, f"Frequency ({shapes_reading('freq_hz')}).", unit="Hz",
                          gt=0.0)
    cycles: int | None = spec(None, f"Number of cycles ({shapes_reading('cycles')}; default: "
                              "until stopped).", min=1)
    to_bar: float | None = spec(None, f"Target ({shapes_reading('to_bar')}).", unit="bar",
                                min=0.0)
    rate_bar_per_s: float | None = spec(None, "Ramp rate.", unit="bar/s", gt=0.0)
    rise_s: float | None = spec(None, "Step edge duration.", unit="s", gt=0.0)
    duration_s: float | None = spec(None, f"Duration ({shapes_reading('duration_s')}).",
                                    unit="s", gt=0.0)
    lead_in_bar_per_s: float = spec(1.0, "Lead-in ramp rate from the present pressure.",
                                    unit="bar/s", gt=0.0)
    # Length profiles (length_force and position modes), in contraction (fraction of the
    # nominal length); the *_bar fields above do not apply to them.
    # (a fraction of the nominal length: no muscle gets anywhere near -1 or 1; the
    # handler holds each to the muscle's own limits and load)
    min_contraction: float | None = spec(None, "Length profile: least contraction ("
                                         f"{shapes_reading('min_bar')}), e.g. 0.05.",
                                         gt=-1.0, max=1.0)
    max_contraction: float | None = spec(None, "Length profile: most contraction, e.g. 0.20.",
                                         gt=-1.0, max=1.0)
    to_contraction: float | None = spec(None, "Length profile: target ("
                                        f"{shapes_reading('to_bar')}).", gt=-1.0, max=1.0)
    rate_per_s: float | None = spec(None, "Length profile: ramp rate, contraction per second.",
                                    unit="1/s", gt=0.0)
    lead_in_per_s: float | None = spec(None, "Length profile: lead-in rate from the present "
                                       "target (default: half control.position."
                                       "max_rate_per_s).", unit="1/s", gt=0.0)


LENGTH_PROFILE_FIELDS = ("min_contraction", "max_contraction", "to_contraction", "rate_per_s",
                         "lead_in_per_s")


@dataclass(frozen=True, kw_only=True)
class ModeArgs:
    muscle: str | None = spec(None, "Muscle name (default: every muscle).")
    mode: str = spec(doc="pressure, length_force or position.")
    feedforward: bool = spec(True, "position: use the muscle's model (false: the position "
                             "PID alone, no model needed).")
    ilc: bool = spec(False, "position: learn a correction over the cycles of a periodic "
                     "length profile (iterative learning control).")


@dataclass(frozen=True, kw_only=True)
class ModelArgs:
    muscle: str = spec(doc="Muscle name.")
    file: str = spec(doc="Model file (pamd train) on the rig PC: over the network, its "
                     "name in the daemon's telemetry.models_dir (no directories); read, "
                     "checked and compiled before the command reaches the loop.")


@dataclass(frozen=True, kw_only=True)
class AdaptArgs:
    muscle: str | None = spec(None, "Muscle name (default: every muscle).")
    action: str = spec("status", "on (adapt the model while a length mode runs; also "
                       "resumes after a freeze), off (keep the adapted model, stop "
                       "adapting), reset (the covariance to its start), restore (the "
                       "trained model back), status, or parameters (a copy of the adapted "
                       "consequents for `pamd model save`).")


@dataclass(frozen=True, kw_only=True)
class HomeArgs:
    muscle: str = spec(doc="Muscle name.")
    length_mm: float = spec(doc="The muscle's true length at its present position.", unit="mm",
                            gt=0.0)


@dataclass(frozen=True, kw_only=True)
class TareArgs:
    muscle: str | None = spec(None, "Muscle name (default: every muscle).")
    load_kg: float | None = spec(None, "Tare against this load hanging on the load cell (it "
                                 "must be the configured load); default: none hangs.",
                                 unit="kg", min=0.0)


@dataclass(frozen=True, kw_only=True)
class LoadArgs:
    muscle: str = spec(doc="Muscle name.")
    load_kg: float = spec(doc="The hanging load now on the muscle.", unit="kg", min=0.0)


@dataclass(frozen=True, kw_only=True)
class NoArgs:
    pass


@dataclass(frozen=True, kw_only=True)
class CollectArgs:
    plan_file: str = spec(doc="Experiment plan (YAML) on the rig PC: its name in the "
                          "daemon's telemetry.plans_dir (no directories).")
    start_step: int = spec(0, "Start at this step (0-based; --resume).", min=0)
    collection: str | None = spec(
        None, "With start_step > 0: the collection to resume, by its directory name under "
        "the daemon's recording directory (the collect reply names it); default: the "
        "newest unfinished one of this plan.")


@dataclass(frozen=True, kw_only=True)
class EstopArgs:
    reason: str = spec("emergency stop", "Why (recorded).")


@dataclass
class Command:
    """A parsed command on its way to the loop; `reply` receives the verdict."""

    verb: str
    args: Any  # Any: the verb's own args dataclass (`Verb.args`), which its handler names
    reply: Callable[[JsonObject], None] | None = None
    sender: str = "local"
    user: str = ""


MAX_TEXT_CHARS = 200
"""Text fields (`reason`, a muscle's name, a file name...) are cut to this when parsed,
so an `estop` or `stop` always fits the rings and always acts."""
MAX_WHO_CHARS = 64  # `sender` and `user`
MAX_ERROR_CHARS = 600  # a refusal's text
RECORD_HEAD_BYTES = 256  # what a recorded refusal keeps of a large payload


def cap_text(text: str, limit: int = MAX_TEXT_CHARS) -> str:
    """`text` cut to `limit` characters, saying how much was cut."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... [{len(text) - limit} more characters cut]"


def cap_payload(payload: JsonObject) -> JsonObject:
    """A payload whose text values and field names are capped (see MAX_TEXT_CHARS)."""
    return {cap_text(str(k)): cap_text(v) if isinstance(v, str) else v
            for k, v in payload.items()}


def args_for_record(payload: JsonValue) -> JsonObject:
    """What a recorded refusal keeps of a request: the payload if small, else its first
    RECORD_HEAD_BYTES bytes (as text) and its size."""
    if isinstance(payload, (bytes, bytearray)):
        text = bytes(payload[:RECORD_HEAD_BYTES * 4]).decode("utf-8", "replace")
        size = len(payload)
    elif isinstance(payload, str):
        text, size = payload, len(payload.encode("utf-8", "replace"))
    else:
        try:
            text = json.dumps(payload, default=str)
        except (ValueError, TypeError, RecursionError):
            text = repr(type(payload))
        size = len(text.encode("utf-8", "replace"))
        if isinstance(payload, dict) and size <= RECORD_HEAD_BYTES:
            return payload
    if size <= RECORD_HEAD_BYTES:
        return {"raw": text}
    head = text.encode("utf-8", "replace")[:RECORD_HEAD_BYTES].decode("utf-8", "ignore")
    return {"head": head, "bytes": size}

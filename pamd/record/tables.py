"""A pamd recording's messages as rows: the loop's, each muscle's state, and the
events, decoded once (`read_tables`). The recording API (`pamd.view.recording`) and
training's reader (`pamd.models.anfis.recordings`) build their columns from these."""

from __future__ import annotations

import json
from dataclasses import dataclass, field

from pamd.declare.jsonsafe import JsonObject
from pamd.record import files


@dataclass(frozen=True)
class RawEvent:
    """One message of the `/events` topic (JSON), as recorded."""

    t_s: float
    tick: int
    kind: str
    data: JsonObject
    log_ns: int


@dataclass
class Tables:
    """Field names and rows of the loop topic and of each muscle's state topic."""

    loop_names: list[str] = field(default_factory=list)
    loop_rows: list[files.Row] = field(default_factory=list)
    muscles: dict[str, tuple[list[str], list[files.Row]]] = field(default_factory=dict)
    events: list[RawEvent] = field(default_factory=list)


def read_tables(path: str, only: str | None = None) -> Tables:
    """Every message of the recording at `path` (or of muscle `only` and the loop);
    `RecordingError` if it cannot be read. A muscle is named by its channel's `muscle`
    metadata, else by the last part of its `/state/<muscle>` topic."""
    dec = files.Decoder()
    t = Tables()
    for ch, schema, msg in files.iter_messages(path):
        topic = ch.topic
        if "/state/" in topic:
            m = ch.metadata.get("muscle") or topic.rsplit("/", 1)[1]
            if only is not None and m != only:
                continue
            table = t.muscles.get(m)
            if table is None:
                table = t.muscles[m] = (dec.columns(ch, schema) or [], [])
            row = dec.decode(ch, schema, msg.data)
            if row is not None:
                table[1].append(row)
        elif topic.endswith("/loop"):
            t.loop_names = t.loop_names or dec.columns(ch, schema) or []
            row = dec.decode(ch, schema, msg.data)
            if row is not None:
                t.loop_rows.append(row)
        elif topic.endswith("/events"):
            try:
                ev = json.loads(msg.data)
            except ValueError:
                continue
            if isinstance(ev, dict):
                t.events.append(RawEvent(float(ev.get("t_s") or 0.0), int(ev.get("tick") or 0),
                                         str(ev.get("kind")), ev.get("data") or {},
                                         msg.log_time))
    return t

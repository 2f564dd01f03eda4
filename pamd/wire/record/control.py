"""Recording control: what the daemon's main thread tells the io process's recorder
while it runs, through the status board's control ring (`pamd.wire.board`, main -> io),
and what the recorder answers (notices, through the board's request ring, io -> main).

A collection started over the network (`pamd cmd collect`, `pamd.daemon.host.collections`)
runs in a daemon that is already recording one continuous run file, so the recorder
learns the collection's directory and steps only when it is asked for:

- `begin` (sent before the plan reaches the loop): at the plan's first step (the tick
  field `segment`, step + 1, turns from 0) the recorder finishes the run's file and
  records each step into a file of its own in the collection's directory, named and
  described (`pamd.experiment` metadata) as `pamd collect` names and describes them.
  When `segment` is back to 0 (the plan ended: done, aborted or failed) it finishes
  the step's file, opens an ordinary run file in its own directory again and says so
  (notice `closed`, with the ticks the collection's files hold).
- `end` (the plan has ended in the loop, or the loop refused it): a collection that
  has not begun is dropped (notice `dropped`); one that has begun closes at its
  `segment` change, as above.

The switches happen at the tick the loop says, never by the main thread's clock: the
io process reads this ring after it has read how far the tick ring goes, and the main
thread writes `begin` before the plan goes to the loop, so every tick of the plan
finds it there.
"""

from __future__ import annotations

import dataclasses
import json

from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.record.record_spec import RecordSpec

BEGIN, END = "begin", "end"
BEGUN, CLOSED, DROPPED = "begun", "closed", "dropped"


def begin_message(cid: int, directory: str, run_name: str, started_at: str,
                  steps: tuple[JsonObject, ...],
                  metadata: dict[str, dict[str, str]]) -> bytes:
    """A collection's files: in `directory`, `<started_at>_<rig>_<run_name>_NN-<step>`,
    each with its step as `pamd.experiment` and `metadata` merged over the run's."""
    return json.dumps({"op": BEGIN, "id": cid, "dir": directory, "run_name": run_name,
                       "started_at": started_at, "steps": list(steps),
                       "metadata": metadata}, default=str).encode()


def end_message(cid: int) -> bytes:
    return json.dumps({"op": END, "id": cid}).encode()


def collection_spec(base: RecordSpec, msg: JsonObject) -> RecordSpec:
    """The run's recording spec turned into the collection's (io process)."""
    meta = {name: dict(rec) for name, rec in base.metadata.items()}
    for name, rec in msg.get("metadata", {}).items():
        meta[name] = {**meta.get(name, {}), **{k: str(v) for k, v in rec.items()}}
    return dataclasses.replace(base, dir=msg["dir"], run_name=msg["run_name"],
                               started_at=msg["started_at"], metadata=meta,
                               steps=tuple(msg["steps"]))


def notice(what: str, msg: JsonObject, **extra: JsonValue) -> JsonObject:
    """A notice of the recorder about collection `msg` (a `begin` message)."""
    return {"what": what, "id": msg["id"], "dir": msg["dir"], **extra}

"""State telemetry: decimated, batched, JSON.

One put per muscle on `pamd/<rig>/state/<muscle>` carries every sample taken since
the last put (at most `telemetry.publish_hz` puts per second; one sample every
`loop.rate_hz / telemetry.rate_hz` ticks). The payload (encoding
`application/json`) is one small object of columns, all of the same length:

    {"v": 1, "rig": "sim", "muscle": "m1", "seq": 41, "t0_wall_s": 1767...,
     "tick": [...], "t_s": [...], "state": [...],
     "pressure_bar": [...], "force_n": [...], ...every pamd.wire.tick.MUSCLE_FIELDS...}

`t_s` is loop time since the run start (the MCAP log time axis); the wall time of a
sample is `t0_wall_s + t_s` (real clock). `state` is the supervisor State number,
`mode` the control Mode, `flags` the Flag bits. Non-finite values (a length before
it is read, no target) are null: the payload is strict JSON. `seq` counts puts per
muscle, so a subscriber sees what the drop congestion policy dropped.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS

VERSION = 1
LOOP_COLUMNS = ("tick", "t_s", "state")
_LOOP_IDX = tuple(LOOP_FIELDS.index(c) for c in LOOP_COLUMNS)
_INF = math.inf


class MuscleBatch:
    """The columns of one muscle's samples since the last put."""

    def __init__(self, rig_id: str, muscle: str, base: int) -> None:
        self.head = {"v": VERSION, "rig": rig_id, "muscle": muscle}
        self.base = base
        self.names = LOOP_COLUMNS + MUSCLE_FIELDS
        self.idx = _LOOP_IDX + tuple(base + j for j in range(len(MUSCLE_FIELDS)))
        self.cols: list[list[float | None]] = [[] for _ in self.names]
        self.n = 0
        self.seq = 0

    def add(self, row: Sequence[float]) -> None:
        for col, i in zip(self.cols, self.idx, strict=True):
            v = row[i]
            col.append(v if -_INF < v < _INF else None)
        self.n += 1

    def take(self, t0_wall_s: float | None) -> bytes:
        msg: JsonObject = dict(self.head, seq=self.seq, t0_wall_s=t0_wall_s)
        for name, col in zip(self.names, self.cols, strict=True):
            msg[name] = col
        self.cols = [[] for _ in self.names]
        self.n = 0
        self.seq += 1
        return json.dumps(msg, separators=(",", ":"), allow_nan=False).encode()


class StateBatcher:
    """Takes every tick record the io process drains; keeps one in `every_ticks`."""

    def __init__(self, rig_id: str, muscles: Sequence[str], every_ticks: int) -> None:
        n_loop, n_m = len(LOOP_FIELDS), len(MUSCLE_FIELDS)
        self.every = every_ticks
        self.batches = [MuscleBatch(rig_id, m, n_loop + k * n_m) for k, m in enumerate(muscles)]
        self.pending = 0

    def add(self, row: Sequence[float]) -> None:
        if int(row[0]) % self.every:
            return
        for b in self.batches:
            b.add(row)
        self.pending += 1


def decode(payload: bytes) -> JsonObject:
    """A state put as a dict of columns (clients, tests)."""
    state: JsonObject = json.loads(payload)
    return state


def rows(msg: JsonObject) -> list[JsonObject]:
    """A decoded state put as one dict per sample."""
    names = [k for k, v in msg.items() if isinstance(v, list)]
    return [{k: msg[k][i] for k in names} for i in range(len(msg.get("tick", [])))]

"""`pamd.connect`: a running daemon from a script or a notebook, over Zenoh.

    with pamd.connect(endpoint="tcp/127.0.0.1:7447") as rig:   # the one rig alive
        rig.status()["state"]                                    # "IDLE"
        rig.command("setpoint", muscle="m1", bar=2.0)            # the loop's verdict
        for batch in rig.stream("m1", duration_s=2.0):           # numpy columns
            print(batch["pressure_bar"].mean())

The same key space `pamd status`, `pamd cmd` and `pamd watch` use (`pamd.client.remote`):
commands carry the daemon's token (found where the daemon writes it, or
`token_file=`), are checked by the io process and the loop, and answered with the loop's
verdict (which names the `rig` that gave it); a refusal raises `CommandRefused` (or,
with `check=False`, is returned).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from pamd.client.remote import Client
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import CommandRefused
from pamd.wire.keys import Keys
from pamd.wire.telemetry import decode
from pamd.wire.zconf import NoDaemon

STREAM_POLL_S = 0.005


@dataclass(frozen=True)
class StateBatch:
    """One state put of a muscle: every sample since the previous put, as columns
    (tick, t_s, state, then every tick field; NaN where the daemon sent null)."""

    muscle: str
    seq: int  # per muscle: a gap means puts were dropped on the way (drop policy)
    t0_wall_s: float | None  # wall-clock time of t_s = 0
    columns: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns.get("tick", ()))


def to_batch(msg: JsonObject) -> StateBatch:
    cols: dict[str, np.ndarray] = {}
    for k, v in msg.items():
        if isinstance(v, list):
            arr = np.array([math.nan if x is None else x for x in v], dtype=np.float64)
            cols[k] = arr.astype(np.int64) if k in ("tick", "mode", "flags", "state") else arr
    return StateBatch(muscle=str(msg.get("muscle")), seq=int(msg.get("seq", -1)),
                      t0_wall_s=msg.get("t0_wall_s"), columns=cols)


class RigClient:
    """One rig of a running daemon. Close it (or use `with`)."""

    def __init__(self, rig: str | None = None, endpoint: str | None = None,
                 zenoh_config: str | None = None, timeout_s: float = 3.0,
                 token_file: str | None = None) -> None:
        self._client = Client(zenoh_config, endpoint, token_file)
        try:
            self.rig: str = self._client.rig(rig, timeout_s=timeout_s)
        except BaseException:
            self._client.close()
            raise
        self.keys = Keys(self.rig)
        self.timeout_s = timeout_s

    def close(self) -> None:
        self._client.close()

    def __enter__(self) -> RigClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RigClient(rig={self.rig!r}, via {self._client.where})"

    def status(self) -> JsonObject:
        """The daemon's status: state, muscles (latest values, limits), timing, faults."""
        return self._client.status(self.rig, self.timeout_s)

    def command(self, verb: str, check: bool = True, timeout_s: float = 10.0,
                **fields: JsonValue) -> JsonObject:
        """Send `verb` with `fields` (as `pamd cmd` does); the loop's verdict. A refusal
        raises CommandRefused with the reason, unless `check=False`."""
        verdict = self._client.command(self.rig, verb, fields, timeout_s=timeout_s)
        if check and not verdict.get("ok"):
            raise CommandRefused(f"{verb}: {verdict.get('error', 'refused')}")
        return verdict

    def stream(self, muscle: str | None = None, duration_s: float | None = None,
               max_batches: int | None = None) -> Iterator[StateBatch]:
        """State batches as they arrive (every muscle, or `muscle`), until `duration_s`
        has passed or `max_batches` came; the subscription ends with the iterator.
        NoDaemon if the daemon goes away meanwhile."""
        key = self.keys.state(muscle) if muscle else self.keys.state_all
        sub = self._client.subscribe(key)
        end = None if duration_s is None else time.monotonic() + duration_s
        n = 0
        try:
            while (end is None or time.monotonic() < end) and (max_batches is None
                                                                or n < max_batches):
                sample = sub.try_recv()
                if sample is None:
                    if self._client.lost:  # its session closed with the daemon
                        raise NoDaemon(f"rig {self.rig}: the daemon went away while "
                                       "streaming")
                    time.sleep(STREAM_POLL_S)
                    continue
                n += 1
                yield to_batch(decode(sample.payload.to_bytes()))
        finally:
            with contextlib.suppress(Exception):  # a session closed with its daemon
                sub.undeclare()

    def record(self, duration_s: float, muscle: str | None = None
               ) -> dict[str, dict[str, np.ndarray]]:
        """`duration_s` of live state joined per muscle: muscle -> column -> array."""
        parts: dict[str, list[StateBatch]] = {}
        for b in self.stream(muscle, duration_s=duration_s):
            parts.setdefault(b.muscle, []).append(b)
        return {m: {k: np.concatenate([b.columns[k] for b in bs]) for k in bs[0].columns}
                for m, bs in parts.items()}


def connect(rig: str | None = None, endpoint: str | None = None,
            zenoh_config: str | None = None, timeout_s: float = 3.0,
            token_file: str | None = None) -> RigClient:
    """A client of the running daemon of `rig` (a name, never a pattern: BadRigName;
    None: the one rig alive, NoDaemon listing them if several answer), reached at
    `endpoint` (default tcp/127.0.0.1:7447) or as the Zenoh client config file says.
    Commands carry the daemon's token, from `token_file` or found as
    `pamd.wire.credential.find_token` says. NoDaemon (a PamdError) if none answers."""
    return RigClient(rig, endpoint, zenoh_config, timeout_s, token_file)

"""The `modbus` driver's output side (`drivers/modbus.py`): what the loop wrote, what
the device has, and the requests that bring the device up to date.

An output is sent when its register value changes and re-sent every
`write_refresh_s`, never before the loop has written it (start-up reads before it
writes); a block whose members are all written goes in one request, one not yet
complete member by member. A module with a communication watchdog gets the outputs'
safe values written once to its safe-value registers (again after a reconnect: the
device may have restarted).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Protocol

from pamd.drivers.modbus_map import Block, ModbusPoint, encode, to_raw

#: what a write request carries: one coil, one register, or several of either
Payload = bool | int | list[bool] | list[int]


class Requester(Protocol):
    """The driver's side a writer needs: one transaction (the response, or a message
    naming the device, request and channels) and its counters."""

    def request(self, fn: str, address: int, arg: Payload, names: tuple[str, ...],
                label: str) -> object | str: ...

    def count(self, key: str, n: int = 1) -> None: ...


class OutputWriter:
    """The outputs of one device: the loop's values (channel unit) and the device's."""

    def __init__(self, points: tuple[ModbusPoint, ...], blocks: Sequence[Block],
                 refresh_s: float) -> None:
        self.points = points
        self.blocks = blocks
        self._refresh_s = refresh_s
        n = len(points)
        self._out: list[float] = [math.nan] * n  # latest value from the loop (volts)
        self._sent: list[float | None] = [None] * n  # raw value the device has
        self._sent_t: list[float] = [-math.inf] * n
        self._safe_want: dict[int, float] = {}
        self._safe_sent: dict[int, float] = {}

    def store(self, index: int, value: float) -> bool:
        """The loop's value for output `index`; False (not stored) for a NaN, which
        never reaches a device."""
        if value != value:
            return False
        self._out[index] = value
        return True

    def set_safe(self, values: dict[int, float]) -> int:
        """Values (channel unit) for the comm-safety registers; returns how many outputs
        have no `safe_address` (unsupported)."""
        want, unsupported = {}, 0
        for i, v in values.items():
            if self.points[i].safe_address is None:
                unsupported += 1
            elif v == v:
                want[i] = v
        self._safe_want = want
        return unsupported

    def forget(self) -> None:
        """A new connection: the device may have restarted, so everything is re-sent."""
        self._sent = [None] * len(self.points)
        self._safe_sent = {}

    def write_outputs(self, req: Requester) -> str | None:
        """Send what changed or is due for a refresh; the first problem, or None."""
        now = time.monotonic()
        refresh = self._refresh_s
        problem = None
        for blk in self.blocks:
            raws: list[float] = []
            due = False
            for i, _off in blk.members:
                v = self._out[i]
                if v != v:
                    raws = []
                    break
                r = to_raw(self.points[i], v)
                raws.append(r)
                due = due or r != self._sent[i] or now - self._sent_t[i] >= refresh
            if not raws:  # not every member written yet: send those that are, one by one
                for i, _off in blk.members:
                    v = self._out[i]
                    if v == v:
                        problem = self._send(req, [i], [to_raw(self.points[i], v)], now) \
                            or problem
                continue
            if due:
                problem = self._send(req, [i for i, _ in blk.members], raws, now) or problem
        return problem

    def _send(self, req: Requester, idx: list[int], raws: list[float],
              now: float) -> str | None:
        pts = [self.points[i] for i in idx]
        names = tuple(p.name for p in pts)
        payload: Payload
        if len(idx) == 1 and (pts[0].is_bit or pts[0].words == 1):
            fn = "write_coil" if pts[0].is_bit else "write_register"
            payload = bool(raws[0] >= 0.5) if pts[0].is_bit else encode(pts[0], raws[0])[0]
        elif pts[0].is_bit:
            fn, payload = "write_coils", [r >= 0.5 for r in raws]
        else:
            fn = "write_registers"
            payload = [w for p, r in zip(pts, raws, strict=True) for w in encode(p, r)]
        rr = req.request(fn, pts[0].address, payload, names,
                         f"writing {', '.join(names)} at {pts[0].function} {pts[0].address}")
        if isinstance(rr, str):
            return rr
        for i, r in zip(idx, raws, strict=True):
            self._sent[i] = r
            self._sent_t[i] = now
        req.count("writes")
        return None

    def write_safe_values(self, req: Requester) -> str | None:
        """Write the safe values the device does not have yet; the first problem."""
        problem = None
        for i, v in self._safe_want.items():
            pt = self.points[i]
            raw = to_raw(pt, v)
            if self._safe_sent.get(i) == raw or pt.safe_address is None:
                continue
            if pt.is_bit:
                rr = req.request("write_coil", pt.safe_address, raw >= 0.5, (pt.name,),
                                 f"safe value of {pt.name}")
            else:
                rr = req.request("write_registers", pt.safe_address, encode(pt, raw),
                                 (pt.name,), f"safe value of {pt.name}")
            if isinstance(rr, str):
                problem = problem or rr
                continue
            self._safe_sent[i] = raw
            req.count("safe_writes")
        return problem

"""The in-process sink: keeps what the run summary needs (tracking error per muscle,
events, faults), and the local mailbox for commands from the same process."""

from __future__ import annotations

import math
import queue
from array import array
from collections import deque
from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

from pamd.loop.safety.limiter import held_back
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import (
    I_STATE,
    I_T,
    M_FLAGS,
    M_LENGTH,
    M_PRESSURE,
    M_SETPOINT,
    M_TARGET_LENGTH,
    M_VALVE_CMD,
    Flag,
    Sink,
    State,
    TickLayout,
)

if TYPE_CHECKING:  # what the mailbox holds (a type only: the sink needs no verbs to run)
    from pamd.wire.verbs.args import Command


class _Cycles(Protocol):
    @property
    def cycle(self) -> int: ...


class _Follows(Protocol):
    """A muscle as the summary reads it (`pamd.loop.control.muscle.MuscleController`)."""

    @property
    def profile(self) -> _Cycles | None: ...


_RUNNING = float(int(State.RUNNING))
_AT_LIMIT = int(Flag.SOFT_LIMIT_PRESSURE | Flag.SOFT_LIMIT_CONTRACTION | Flag.PRETENSION_LIMIT)
EVENTS_KEPT = 1000


class SummarySink:
    """Accumulates tracking errors while RUNNING (measured pressure vs the setpoint,
    which is the profile's target: no limit or guard ever writes it, so a profile a
    limit holds back shows as tracking error; in the length modes measured length vs
    target length), the time a soft limit held the valve command back while RUNNING,
    and the run's events (`soft_limit` events: a profile held at a limit > 1 s).
    With the muscles to follow (`follow_cycles`), the tracking errors also after the
    profile's first cycle (its lead-in and first cycle left out: the span the docs'
    and the benchmarks' tracking figures are computed over).
    Constant work per tick; no allocation."""

    def __init__(self, layout: TickLayout) -> None:
        self.layout = layout
        n = len(layout.muscles)
        self.sq = [0.0] * n
        self.abs_sum = [0.0] * n  # sum |e|: the MAE (seed 003's tracking metric)
        self.max_abs = [0.0] * n
        self.count = [0] * n
        self.len_sq = [0.0] * n
        self.len_abs_sum = [0.0] * n
        self.len_max_abs = [0.0] * n
        self.len_count = [0] * n
        self.limited_s = [0.0] * n
        self.limit_events = [0] * n
        # after the first cycle: [squares, max |e|, count] of pressure, then of length,
        # then sum |e| of pressure and of length
        self.steady = [[0.0, 0.0, 0, 0.0, 0.0, 0, 0.0, 0.0] for _ in range(n)]
        self._muscles: Sequence[_Follows] = ()
        self._last_t = 0.0
        self.ticks = 0
        # the latest events (the recording keeps them all): a daemon that runs for
        # weeks and takes commands must not grow by each one
        self.events: deque[tuple[float, str, JsonObject]] = deque(maxlen=EVENTS_KEPT)
        self._bases = [b for b in layout.muscle_base]
        self.downstream: list[Sink] = []  # the io process's ring sink, a probe

    def follow_cycles(self, muscles: Sequence[_Follows]) -> None:
        """Read each muscle's running profile (same order as the layout) to tell the
        ticks after its first cycle."""
        self._muscles = muscles

    def put(self, record: array[float]) -> bool:
        self.ticks += 1
        t = record[I_T]
        dt = t - self._last_t
        self._last_t = t
        if record[I_STATE] == _RUNNING:
            muscles = self._muscles
            for k, b in enumerate(self._bases):
                if muscles:
                    p = muscles[k].profile
                    if p is not None and p.cycle >= 1:
                        self._steady(k, record, b)
                flags = int(record[b + M_FLAGS])
                if flags & _AT_LIMIT and held_back(flags, record[b + M_SETPOINT],
                                                   record[b + M_VALVE_CMD]):
                    self.limited_s[k] += dt
                e = record[b + M_SETPOINT] - record[b + M_PRESSURE]
                if e == e:
                    a = abs(e)
                    self.sq[k] += e * e
                    self.abs_sum[k] += a
                    self.count[k] += 1
                    if a > self.max_abs[k]:
                        self.max_abs[k] = a
                e = record[b + M_TARGET_LENGTH] - record[b + M_LENGTH]  # NaN: no target
                if e == e:
                    a = abs(e)
                    self.len_sq[k] += e * e
                    self.len_abs_sum[k] += a
                    self.len_count[k] += 1
                    if a > self.len_max_abs[k]:
                        self.len_max_abs[k] = a
        ok = True
        for d in self.downstream:
            ok = d.put(record) and ok
        return ok

    def _steady(self, k: int, record: array[float], b: int) -> None:
        s = self.steady[k]
        e = record[b + M_SETPOINT] - record[b + M_PRESSURE]
        if e == e:
            s[0] += e * e
            s[2] += 1
            s[6] += abs(e)
            if abs(e) > s[1]:
                s[1] = abs(e)
        e = record[b + M_TARGET_LENGTH] - record[b + M_LENGTH]
        if e == e:
            s[3] += e * e
            s[5] += 1
            s[7] += abs(e)
            if abs(e) > s[4]:
                s[4] = abs(e)

    def event(self, t_s: float, name: str, data: JsonObject) -> None:
        self.events.append((t_s, name, data))
        if name == "soft_limit" and data.get("muscle") in self.layout.muscles:
            self.limit_events[self.layout.muscles.index(data["muscle"])] += 1
        for d in self.downstream:
            d.event(t_s, name, data)

    def close(self) -> None:
        for d in self.downstream:
            d.close()

    def tracking(self) -> dict[str, dict[str, float | None]]:
        """Per muscle: pressure tracking against the profile's target (`rmse_bar`,
        `mae_bar`, `max_error_bar`, `samples`), length tracking in the length modes
        (`length_rmse_mm`, `length_mae_mm`, `length_max_error_mm`, `length_samples`;
        MAE and RMSE are seed 003's tracking metrics), None where nothing
        was tracked; the same after the profile's first cycle (`..._after_first_cycle`:
        None for a profile of one cycle or none); and how long a soft limit held the
        command back while RUNNING (`soft_limit_s`) with the number of `soft_limit`
        events (held > 1 s)."""
        out: dict[str, dict[str, float | None]] = {}
        for k, m in enumerate(self.layout.muscles):
            n, n_len = self.count[k], self.len_count[k]
            sq, mx, ns, lsq, lmx, nls, sa, lsa = self.steady[k]
            out[m] = {
                "rmse_bar": math.sqrt(self.sq[k] / n) if n else None,
                "mae_bar": self.abs_sum[k] / n if n else None,
                "max_error_bar": self.max_abs[k] if n else None,
                "samples": n,
                "length_rmse_mm": math.sqrt(self.len_sq[k] / n_len) if n_len else None,
                "length_mae_mm": self.len_abs_sum[k] / n_len if n_len else None,
                "length_max_error_mm": self.len_max_abs[k] if n_len else None,
                "length_samples": n_len,
                "rmse_bar_after_first_cycle": math.sqrt(sq / ns) if ns else None,
                "mae_bar_after_first_cycle": sa / ns if ns else None,
                "max_error_bar_after_first_cycle": mx if ns else None,
                "samples_after_first_cycle": int(ns),
                "length_rmse_mm_after_first_cycle": math.sqrt(lsq / nls) if nls else None,
                "length_mae_mm_after_first_cycle": lsa / nls if nls else None,
                "length_max_error_mm_after_first_cycle": lmx if nls else None,
                "length_samples_after_first_cycle": int(nls),
                "soft_limit_s": round(self.limited_s[k], 3),
                "soft_limit_events": self.limit_events[k],
            }
        return out


class LocalMailbox:
    """Commands from threads of the same process; `poll` never blocks."""

    def __init__(self) -> None:
        self._q: queue.SimpleQueue[Command] = queue.SimpleQueue()

    def put(self, cmd: Command) -> None:
        self._q.put(cmd)

    def poll(self) -> Command | None:
        if self._q.empty():  # the common case, without raising queue.Empty
            return None
        try:
            return self._q.get_nowait()
        except queue.Empty:
            return None

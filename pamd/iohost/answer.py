"""The answer to a `status` query (`pamd/<rig>/status`), built in the io process from
the board's snapshot (the daemon's main thread writes it every 1 / status_hz) with the
loop's latest tick record over it, and said to be stale, with the reasons, when the
snapshot is old or the loop is not running; and the loop's timing in it (`TickStats`),
kept by the io process from the tick records it drains (each record carries its
wake-up latency, compute time, overruns and lost records), so that the loop's process
never spends time on percentiles for status queries. Histograms of 1 us bins like
`pamd.loop.tick_timing.Histogram`; percentiles at most every `period_s`, in the io loop.

Stale, for the live values, means the loop is not running, judged by the loop's own
rule: it has written no tick record into its ring for longer than its stall fault
limit (`loop.stall_fault_s`, derived from what the actuation holds: past it the loop
latches FAULT when it runs again, since the outputs may no longer be what it wrote).
The io process reads the newest record the loop wrote without draining it, so an io
process that is merely behind (a loaded PC: it drains in batches) does not make a
healthy rig's status STALE, as "no tick records for 0.5 s" did: how far behind it is,
is said (`live_lag_s`), and records it lost to a full ring count as the loop running.
The virtual clock's time is no wall time: there the rule stays the io process's own
(no records drained for LIVE_STALE_MIN_S or LIVE_STALE_TICKS)."""

from __future__ import annotations

import bisect
import contextlib
import itertools
import json
import math
from array import array
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.net_spec import NetSpec
from pamd.wire.tick import (
    I_COMPUTE,
    I_LOST,
    I_OVERRUNS,
    I_STATE,
    I_T,
    I_TICK,
    I_WAKE,
    LOOP_FIELDS,
    MUSCLE_FIELDS,
    Mode,
    State,
)

if TYPE_CHECKING:  # ports: types only, so the io process never loads them
    from pamd.wire.seams import LoopStart, RunClock

#: what a status answer takes from the latest tick record rather than the snapshot
LIVE_FIELDS = ("pressure_bar", "setpoint_bar", "valve_cmd_bar", "force_n", "length_mm",
               "contraction")
SNAPSHOT_STALE_MIN_S, SNAPSHOT_STALE_PERIODS = 1.0, 5  # a snapshot older is stale
LIVE_STALE_MIN_S, LIVE_STALE_TICKS = 0.5, 50  # tick records older are stale
STATUS_REUSE_S = 0.02  # an answer serves the status queries of this long
MAX_US = 100_000  # the timing histograms' top bin (1 us each): 100 ms


def percentiles(bins: array[int], qs: tuple[float, ...], top: int = MAX_US) -> list[float]:
    """The bins' percentiles `qs` (in bins, 1 us each): the first bin whose cumulative
    count reaches q% of the total (numpy's searchsorted, side left). Plain Python (C
    speed: accumulate, bisect), so the io process needs no numpy. `top`: the highest
    bin that may hold a count (the largest value seen), so only those are summed."""
    cum = list(itertools.accumulate(bins[:min(top, MAX_US) + 1]))
    total = cum[-1]
    if total == 0:
        return [0.0 for _ in qs]
    return [float(bisect.bisect_left(cum, q / 100.0 * total)) for q in qs]


def _top_bin(max_s: float) -> int:
    """The bin `add` put the largest value in (and every smaller one below it)."""
    return max(0, int(max_s * 1e6 + 0.5))


class TickStats:
    """The loop's timing (wake-up latency, compute time) from the drained tick records."""

    def __init__(self, period_s: float = 0.5) -> None:
        self.wake = array("q", bytes(8 * (MAX_US + 1)))
        self.compute = array("q", bytes(8 * (MAX_US + 1)))
        self.wake_max_s = self.compute_max_s = 0.0
        self.last: Sequence[float] | None = None
        self.period_s = period_s
        self.t = -1e9
        self.summary: JsonObject = {}

    def add(self, rows: Sequence[Sequence[float]]) -> None:
        wake, comp, top = self.wake, self.compute, MAX_US
        wmax, cmax = self.wake_max_s, self.compute_max_s
        for row in rows:
            w, c = row[I_WAKE], row[I_COMPUTE]
            wake[min(top, max(0, int(w * 1e6 + 0.5)))] += 1
            comp[min(top, max(0, int(c * 1e6 + 0.5)))] += 1
            if w > wmax:
                wmax = w
            if c > cmax:
                cmax = c
        self.wake_max_s, self.compute_max_s = wmax, cmax
        self.last = rows[-1]

    def refresh(self, now: float) -> None:
        """Recompute the percentiles if `period_s` has passed (the io loop)."""
        if now - self.t < self.period_s or self.last is None:
            return
        self.t = now
        w50, w99 = percentiles(self.wake, (50.0, 99.0), _top_bin(self.wake_max_s))
        c50, c99 = percentiles(self.compute, (50.0, 99.0), _top_bin(self.compute_max_s))
        last = self.last
        self.summary = {
            "ticks": int(last[I_TICK]) + 1, "overruns": int(last[I_OVERRUNS]),
            "lost_records": int(last[I_LOST]),
            "wake_latency_us": {"p50": w50, "p99": w99, "max": self.wake_max_s * 1e6},
            "compute_us": {"p50": c50, "p99": c99, "max": self.compute_max_s * 1e6},
            "source": "the tick records the io process drained",
        }


class StatusAnswer:
    """Builds status answers for one node (its spec, its run clock, its tick stats)."""

    def __init__(self, spec: NetSpec, io_spec: RunClock, stats: TickStats,
                 block: LoopStart) -> None:
        self.spec = spec
        self.io_spec = io_spec
        self.stats = stats
        self.block = block  # how far the loop is (its newest record, its lost count)
        self._lost_seen = 0
        self._lost_t = -math.inf  # when the lost count last grew (the loop ran then)
        n_loop, n_m = len(LOOP_FIELDS), len(MUSCLE_FIELDS)
        self.live = [(m, n_loop + k * n_m) for k, m in enumerate(spec.muscles)]
        self.live_idx = [(f, MUSCLE_FIELDS.index(f)) for f in LIVE_FIELDS]
        self.i_mode, self.i_flags = MUSCLE_FIELDS.index("mode"), MUSCLE_FIELDS.index("flags")
        self._served: bytes | None = None  # the latest answer, and when it was built
        self._served_t = -1e9
        self.local: str | None = None  # the local channel's path, when it listens
        self.notes: list[str] = []  # what the operator should know of this node

    def serve(self, read: Callable[[], tuple[bytes, float] | None], now: float,
              rows_mono: float, stopping: str | None, io_counts: dict[str, int]) -> bytes:
        """`body`, built at most once per STATUS_REUSE_S (`read`: the board's snapshot):
        a storm of status queries costs the io process a bounded rate of answers."""
        if self._served is None or now - self._served_t >= STATUS_REUSE_S:
            self._served = self.body(read(), now, rows_mono, stopping, io_counts)
            self._served_t = now
        return self._served

    def body(self, snapshot: tuple[bytes, float] | None, now: float, rows_mono: float,
             stopping: str | None, io_counts: dict[str, int]) -> bytes:
        """The JSON answer: `snapshot` is the board's (blob, age in s) or None, `now` and
        `rows_mono` (when tick records last came in) are monotonic times."""
        if snapshot is None:
            return json.dumps({"ok": False, "rig_id": self.spec.rig_id,
                               "error": "no status yet: the daemon is starting"}).encode()
        blob, age = snapshot
        try:
            st = json.loads(blob)
        except ValueError:
            st = {"error": "the status snapshot is not JSON"}
        loop_age, lag = self.loop_age(now, rows_mono)
        stale = self.staleness(age, loop_age)
        if self.stats.last is not None:  # which record the io process drained last
            st["tick"], st["t_s"] = int(self.stats.last[I_TICK]), self.stats.last[I_T]
        if self._fresher(now - age, bool(stale)):
            self._live(st)  # the loop's latest values over the snapshot, when not older
        lost = self.block.loop_lost()
        rec = st.get("recording")
        if isinstance(rec, dict):
            rec["lost_records"] = max(lost, int(rec.get("lost_records") or 0))
        st.update(ok="error" not in st, snapshot_age_s=round(age, 4),
                  stopping=stopping or st.get("stopping"), timing=self.stats.summary,
                  io=dict(io_counts), stale=bool(stale), stale_reasons=stale,
                  live_lag_s=lag, lost_records=lost,
                  command_nonce=self.spec.run_nonce, local_channel=self.local,
                  warnings=[*self.spec.warnings, *self.notes])
        return json.dumps(st, default=str).encode()

    def loop_age(self, now: float, rows_mono: float) -> tuple[float | None, float | None]:
        """(how long ago the loop last wrote a tick record or lost one, how far the live
        values are behind its newest record), in seconds; None where not known yet.
        On the virtual clock: (since the io process last drained records, None)."""
        if self.stats.last is None:
            return None, None
        if self.io_spec.virtual:
            return now - rows_mono, None
        t0, newest = self.block.t_start(), self.block.newest_f64(I_T)
        if t0 is None or newest is None:
            return None, None
        lost = self.block.loop_lost()
        if lost != self._lost_seen:  # it lost records since: it was running then
            self._lost_seen, self._lost_t = lost, now
        age = max(0.0, min(now - (t0 + newest), now - self._lost_t))
        return age, round(max(0.0, newest - self.stats.last[I_T]), 4)

    def _fresher(self, snapshot_t: float, stale: bool) -> bool:
        """Whether the latest tick record drained is as new as the snapshot (built at
        `snapshot_t`, monotonic), within one snapshot period: an io process further
        behind has older values than the main thread's snapshot, which then stands.
        The virtual clock: unless stale."""
        last, t0 = self.stats.last, self.block.t_start()
        if self.io_spec.virtual or t0 is None or last is None:
            return not stale
        return t0 + last[I_T] >= snapshot_t - self.spec.status_period_s

    def staleness(self, snapshot_age_s: float, loop_age_s: float | None) -> list[str]:
        """Why the answer may not be the rig's present state (empty: it is)."""
        out = []
        limit = max(SNAPSHOT_STALE_MIN_S, SNAPSHOT_STALE_PERIODS * self.spec.status_period_s)
        if snapshot_age_s > limit:
            out.append(f"the daemon's main thread has not refreshed the status for "
                       f"{snapshot_age_s:.1f} s (it does every {self.spec.status_period_s:g} s)")
        if loop_age_s is None:
            return out
        if self.io_spec.virtual:
            if loop_age_s > max(LIVE_STALE_MIN_S, LIVE_STALE_TICKS / self.io_spec.rate_hz):
                out.append(f"no tick records from the loop for {loop_age_s:.1f} s: live "
                           "values are the last drained")
        elif loop_age_s > self.spec.stall_fault_s:
            out.append(f"the loop has written no tick record for {loop_age_s:.1f} s, past "
                       f"its stall limit ({self.spec.stall_fault_s:g} s): it is not running; "
                       "live values are its last")
        return out

    def _live(self, st: JsonObject) -> None:
        """The latest tick record's values over the snapshot's (which may be up to
        1 / status_hz old)."""
        row = self.stats.last
        if row is None:
            return
        with contextlib.suppress(ValueError):
            st["state"] = State(int(row[I_STATE])).name
        ms = st.get("muscles") or {}
        for name, base in self.live:
            d = ms.get(name)
            if d is None:
                continue
            for f, j in self.live_idx:
                v = row[base + j]
                d[f] = v if -math.inf < v < math.inf else None
            with contextlib.suppress(ValueError):
                d["mode"] = Mode(int(row[base + self.i_mode])).name.lower()
            d["flags"] = int(row[base + self.i_flags])

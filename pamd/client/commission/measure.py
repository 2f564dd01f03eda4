"""What the commissioning run's rows say about each signal and the loop (numpy, after
the run; never in the tick).

Per input signal (from its sample stamps, not the loop's period):
- `period_s`: the median time between two new samples (a new stamp); `jitter_s`: the
  standard deviation of those gaps; `worst_gap_s`: the longest;
- `worst_age_s`: the largest age the loop saw (tick time - sample stamp): what the
  signal's timeout is compared with;
- `noise`: the standard deviation at rest around a straight line (drift is not noise);
- `quantum`: the converter's or encoder's step: the smallest change between two
  samples, where every change is a whole number of it (else None: continuous);
- `longest_repeat_s`: the longest time one identical value repeated while the rig moved;
- `jump_excess`: the largest change between two samples beyond what the plausibility
  rate allows over their stamps (+ jitters): what the jump allowance must cover;
- `changes`: the value changed at all.
Per step of the valve command (`Step`): the command's, the pressure's, the length's
and the force's change between the holds before and after, and the latency from the
command to the measured pressure (and length): the time between the command and the
measurement each passing 10 % of their change, as the loop saw them.
The loop: how late it woke (p50, p99, max).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pamd.client.commission.probe import Probe

#: the share of a step's change that marks its response (latency)
LATENCY_SHARE = 0.1
#: the holds' tail averaged before and after a step, s
HOLD_TAIL_S = 0.3
#: changes within this share of the quantum count as whole numbers of it
QUANTUM_TOLERANCE = 0.05

PHASE_REST, PHASE_FIRST, PHASE_MOVES = 1, 2, 3


@dataclass
class SignalStats:
    name: str  # m1.pressure
    unit: str
    samples: int = 0
    period_s: float = math.nan
    jitter_s: float = math.nan
    worst_gap_s: float = math.nan
    worst_age_s: float = math.nan
    declared_jitter_s: float = 0.0
    noise: float = math.nan
    quantum: float | None = None
    longest_repeat_s: float = 0.0
    jump_excess: float = math.nan
    changes: bool = False
    rest_mean: float = math.nan

    def as_dict(self) -> dict[str, object]:
        return {k: _clean(v) for k, v in self.__dict__.items()}


@dataclass
class Step:
    muscle: str
    name: str
    command_change_bar: float
    pressure_change_bar: float
    length_change_mm: float
    force_change_n: float
    pressure_latency_s: float
    length_latency_s: float

    def as_dict(self) -> dict[str, object]:
        return {k: _clean(v) for k, v in self.__dict__.items()}


@dataclass
class LoopStats:
    ticks: int = 0
    wake_p50_s: float = 0.0
    wake_p99_s: float = 0.0
    wake_max_s: float = 0.0
    measured: bool = False  # False on the virtual clock: nothing to measure

    def as_dict(self) -> dict[str, object]:
        return {k: _clean(v) for k, v in self.__dict__.items()}


@dataclass
class Measurements:
    signals: dict[str, SignalStats] = field(default_factory=dict)
    steps: list[Step] = field(default_factory=list)
    loop: LoopStats = field(default_factory=LoopStats)


UNITS = {"pressure": "bar", "force": "N", "length": "mm"}


def _clean(v: object) -> object:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def signal_stats(probe: Probe, muscle: str, signal: str, max_rate: float) -> SignalStats:
    """One signal's figures over all the rows taken so far (see the module's doc);
    `max_rate` the plausibility rate of its signal (per s; 0: no jump check)."""
    st = SignalStats(f"{muscle}.{signal}", UNITS[signal])
    t = probe.column("t")
    phase = probe.column("phase")
    v = probe.column(f"{muscle}.{signal}")
    stamp = probe.column(f"{muscle}.{signal}_stamp")
    jit = probe.column(f"{muscle}.{signal}_jitter")
    seen = np.isfinite(stamp) & np.isfinite(v)
    if not seen.any():
        return st
    age = t[seen] - stamp[seen]
    st.worst_age_s = max(float(age.max()), 0.0)  # a stamp on the tick's own time: 0
    new = seen.copy()
    idx = np.flatnonzero(seen)
    new[idx[1:]] = stamp[idx[1:]] != stamp[idx[:-1]]
    ts, vs, js, ph = stamp[new], v[new], jit[new], phase[new]
    # the probe takes no rows between two phases: a gap or a repeat across that is no
    # measurement (the rows of one phase are contiguous)
    same = ph[1:] == ph[:-1]
    st.samples = len(ts)
    st.declared_jitter_s = float(js.max()) if len(js) else 0.0
    st.changes = bool(len(vs) > 1 and np.ptp(vs) > 0.0)
    gaps = np.diff(ts)[same]
    gaps = gaps[gaps > 0.0]
    if len(gaps) >= 2:
        st.period_s = float(np.median(gaps))
        st.jitter_s = float(np.std(gaps))
        st.worst_gap_s = float(gaps.max())
    rest = ph == PHASE_REST
    if rest.sum() >= 3:
        tr, vr = ts[rest], vs[rest]
        st.rest_mean = float(vr.mean())
        if np.ptp(tr) > 0.0:
            coef = np.polyfit(tr - tr[0], vr, 1)
            st.noise = float(np.std(vr - np.polyval(coef, tr - tr[0])))
        else:
            st.noise = float(np.std(vr))
        if st.noise < 1e-9 * max(1.0, abs(st.rest_mean)):
            st.noise = 0.0  # the fit's rounding: a noiseless sensor
    st.quantum = _quantum(np.diff(vs)[same])
    block = np.concatenate(([0], np.cumsum(~same)))
    moving = ph != PHASE_REST
    st.longest_repeat_s = max((_longest_repeat(ts[(block == b) & moving],
                                               vs[(block == b) & moving])
                               for b in np.unique(block[moving])), default=0.0)
    if max_rate > 0.0 and len(ts) >= 2:
        dt = np.diff(ts)
        ok = (dt > 0.0) & same
        allowed = max_rate * (dt + js[:-1] + js[1:])
        excess = np.abs(np.diff(vs)) - allowed
        st.jump_excess = float(excess[ok].max()) if ok.any() else math.nan
    return st


def _quantum(changes: np.ndarray) -> float | None:
    """The step every change between two samples is a whole number of (None: none)."""
    d = np.abs(changes)
    d = d[d > 1e-9 * max(1.0, float(d.max()) if len(d) else 1.0)]
    if len(d) < 10:
        return None
    q = float(d.min())
    ratio = d / q
    off = np.abs(ratio - np.round(ratio))
    # a continuous signal's smallest change is far below its typical change and its
    # changes are no multiples of it
    if float(np.median(off)) > QUANTUM_TOLERANCE or float(np.median(ratio)) > 1e4:
        return None
    return q


def _longest_repeat(ts: np.ndarray, vs: np.ndarray) -> float:
    if len(vs) < 2:
        return 0.0
    change = np.flatnonzero(np.diff(vs) != 0.0) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change - 1, [len(vs) - 1]))
    return float((ts[ends] - ts[starts]).max())


def loop_stats(probe: Probe, virtual: bool) -> LoopStats:
    wake = probe.column("wake_s")
    wake = wake[np.isfinite(wake)]
    ls = LoopStats(ticks=len(wake), measured=not virtual)
    if len(wake):
        ls.wake_p50_s = float(np.percentile(wake, 50))
        ls.wake_p99_s = float(np.percentile(wake, 99))
        ls.wake_max_s = float(wake.max())
    return ls


def steps_of(probe: Probe, muscle: str, phase: int, names: list[str]) -> list[Step]:
    """The moves of one phase's plan (`names`: its steps, in order): each step's change
    from the tail of what came before it (the previous step's hold, or for the first
    one the rows before the phase) to the tail of its own rows (a phase cut short by a
    fault: as far as it got)."""
    t = probe.column("t")
    ph = probe.column("phase")
    seg = probe.column("segment")
    cols = {c: probe.column(f"{muscle}.{c}") for c in
            ("valve_cmd", "pressure", "length", "force")}
    out: list[Step] = []
    for k, name in enumerate(names):
        during = (ph == phase) & (seg == k + 1)  # segment = the step's index + 1
        idx = np.flatnonzero(during)
        if len(idx) < 3 or idx[0] < 3:
            continue
        i0 = int(idx[0])
        b_tail = np.zeros_like(during)
        b_tail[:i0] = t[:i0] >= t[i0 - 1] - HOLD_TAIL_S
        td = t[during]
        d_tail = during & (t >= td[-1] - HOLD_TAIL_S)
        ch = {c: float(np.nanmean(col[d_tail]) - np.nanmean(col[b_tail]))
              for c, col in cols.items()}
        c0 = float(np.nanmean(cols["valve_cmd"][b_tail]))
        t_cmd = _crossing(td, cols["valve_cmd"][during], c0, ch["valve_cmd"])
        lat = {}
        for c in ("pressure", "length"):
            t_meas = _crossing(td, cols[c][during], float(np.nanmean(cols[c][b_tail])),
                               ch[c])
            lat[c] = t_meas - t_cmd
        out.append(Step(muscle, name, ch["valve_cmd"], ch["pressure"], ch["length"],
                        ch["force"], lat["pressure"], lat["length"]))
    return out


def _crossing(t: np.ndarray, v: np.ndarray, v0: float, change: float) -> float:
    """When `v` first passed `LATENCY_SHARE` of `change` from `v0` (NaN: never)."""
    if not change or not math.isfinite(change):
        return math.nan
    share = (v - v0) / change
    hit = np.flatnonzero(share >= LATENCY_SHARE)
    return float(t[hit[0]]) if len(hit) else math.nan

"""Training pairs for the inverse model, taken from recorded runs.

Role: read runs (MCAP files written by `pamd run --record`, CSV files with named
columns such as `pamd export` writes or a lab's MATLAB export), keep the samples that
show the muscle's steady behaviour, and return inputs X (force, length or
contraction, optionally velocity) and the measured output y (pressure), with a split
into training / validation / test sets that keeps whole time blocks (or whole runs)
together so no test data leaks into training.

What is dropped, per run (counted per reason in the provenance):

* faults and other states: with a state column (MCAP: the loop topic) only RUNNING
  samples are kept (IDLE holds, HOLD, LOAD_CHANGE, FAULT, ESTOP, STARTING are not
  the sweep);
* flagged samples: stale signals, soft limits (pressure, contraction, pretension),
  PID saturation, open exhaust, tracking alarms, unreferenced length (`DROP_FLAGS`);
* settling transients: the first `settle_s` of each run and of each stretch of
  accepted state, and, in MCAP files, each profile's lead-in ramp (computed from the
  profile command recorded on the events topic) plus `settle_s`.

The velocity input is computed from the length at the recording's full rate with
`pamd.control.velocity.filtered_velocity`, the very function the control tick uses
(with the model's window, stored in the model file and used by the tick), and only
then are the samples decimated to `rate_hz` (1 kHz is far more than a model
of a 0.05 Hz sweep needs).

Bad data is refused with `ModelError` naming file, column and problem: a missing
column, NaN/inf among the kept samples, a constant input, too few samples.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pamd.control.velocity import MODEL_VELOCITY_WINDOW_S, derivation, filtered_velocity
from pamd.errors import ModelError, RecordingError
from pamd.tick import Flag, State

#: Model inputs this module can produce, with units.
INPUT_UNITS: dict[str, str] = {
    "force_n": "N", "length_mm": "mm", "contraction": "", "velocity_mm_s": "mm/s",
}
#: Outputs it can produce (measured signals), with units.
OUTPUT_UNITS: dict[str, str] = {"pressure_bar": "bar", "force_n": "N", "length_mm": "mm"}

#: Flag bits whose samples are not training data.
DROP_FLAGS = int(Flag.STALE | Flag.SOFT_LIMIT_PRESSURE | Flag.SOFT_LIMIT_CONTRACTION
                 | Flag.PRETENSION_LIMIT | Flag.OUTPUT_SATURATED | Flag.EXHAUST_OPEN
                 | Flag.TRACKING | Flag.NOT_REFERENCED)

#: Accepted names of a CSV time column (case-insensitive) and their scale to seconds.
TIME_COLUMNS: tuple[tuple[str, float], ...] = (
    ("t_s", 1.0), ("time_s", 1.0), ("time", 1.0), ("t", 1.0), ("log_time_ns", 1e-9),
)

_RUNNING = int(State.RUNNING)
_PROFILE_VERBS = ("profile", "setpoint")


@dataclass
class Run:
    """One recorded run of one muscle: columns at the recording's own rate.

    `columns` holds float arrays by field name (pressure_bar, force_n, length_mm, ...,
    flags, state where known); `events` are (t_s, kind, data) from the events topic.
    """

    source: str
    muscle: str
    t_s: np.ndarray
    columns: dict[str, np.ndarray]
    load_kg: float | None = None
    events: list[tuple[float, str, dict[str, Any]]] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        return f"{self.source} [{self.muscle}]" if self.muscle else self.source


@dataclass(frozen=True)
class ExtractOptions:
    """What to extract and what to drop (see the module docstring)."""

    inputs: tuple[str, ...] = ("force_n", "length_mm")
    output: str = "pressure_bar"
    muscle: str | None = None  # MCAP: only this muscle (default: every muscle, pooled)
    settle_s: float = 2.0  # dropped at the start of each run, state stretch and lead-in
    rate_hz: float = 50.0  # decimated sample rate
    drop_flags: int = DROP_FLAGS
    velocity_window_s: float = MODEL_VELOCITY_WINDOW_S  # the model's velocity filter
    min_samples: int = 50  # fewer kept samples than this is refused

    def check(self) -> None:
        unknown = [n for n in self.inputs if n not in INPUT_UNITS]
        if unknown:
            raise ModelError(f"unknown input(s) {', '.join(unknown)}; inputs are chosen from "
                             f"{', '.join(INPUT_UNITS)}")
        if len(set(self.inputs)) != len(self.inputs) or not self.inputs:
            raise ModelError(f"inputs must be distinct and at least one: {self.inputs}")
        if self.output not in OUTPUT_UNITS:
            raise ModelError(f"unknown output {self.output!r}; use one of "
                             f"{', '.join(OUTPUT_UNITS)}")
        if self.output in self.inputs:
            raise ModelError(f"{self.output} cannot be both an input and the output")
        if not self.rate_hz > 0 or not self.settle_s >= 0:
            raise ModelError("rate_hz must be > 0 and settle_s >= 0")
        if not self.velocity_window_s > 0:
            raise ModelError("the velocity window must be > 0 s")


@dataclass
class Samples:
    """Training pairs: X (n x d) in input units, y (n,), each sample's time and run."""

    X: np.ndarray
    y: np.ndarray
    t_s: np.ndarray
    run: np.ndarray  # index into `runs`
    inputs: tuple[str, ...]
    output: str
    runs: list[dict[str, Any]]  # provenance of each run (source, muscle, load, counts)
    options: ExtractOptions

    def __len__(self) -> int:
        return int(self.y.size)

    @property
    def input_units(self) -> list[str]:
        return [INPUT_UNITS[n] for n in self.inputs]

    @property
    def output_unit(self) -> str:
        return OUTPUT_UNITS[self.output]

    def subset(self, mask: np.ndarray) -> Samples:
        return replace(self, X=self.X[mask], y=self.y[mask], t_s=self.t_s[mask],
                       run=self.run[mask])

    def time_axis(self) -> np.ndarray:
        """A time axis across runs for plots: each run's time offset to follow the last."""
        out = np.empty_like(self.t_s)
        offset = 0.0
        for r in np.unique(self.run):
            sel = self.run == r
            t = self.t_s[sel]
            out[sel] = t - t[0] + offset
            offset = out[sel][-1] + 1.0
        return out

    def provenance(self) -> dict[str, Any]:
        """What the model file says about its data."""
        o = self.options
        loads = sorted({r["load_kg"] for r in self.runs if r.get("load_kg") is not None})
        out: dict[str, Any] = {
            "files": sorted({r["source"] for r in self.runs}),
            "runs": self.runs,
            "loads_kg": loads,
            "samples": len(self),
            "extraction": {
                "settle_s": o.settle_s, "rate_hz": o.rate_hz,
                "drop_flags": [f.name for f in Flag if f & o.drop_flags],
                "states_kept": ["RUNNING"],
                "lead_in_ramps": "dropped (MCAP profile commands)",
                "velocity_window_s": o.velocity_window_s,
            },
        }
        return out


# -- reading ---------------------------------------------------------------------------
def read_runs(paths: Sequence[str], muscle: str | None = None) -> list[Run]:
    """Every run in `paths` (MCAP files by their magic bytes, anything else as CSV)."""
    if not paths:
        raise ModelError("no data files given")
    runs: list[Run] = []
    for p in paths:
        if not os.path.exists(p):
            raise ModelError(f"{p}: no such file")
        if os.path.isdir(p):
            raise ModelError(f"{p}: is a directory; name the .mcap or .csv files in it")
        with open(p, "rb") as fh:
            head = fh.read(8)
        if head.startswith(b"\x89MCAP"):
            runs += read_mcap(p, muscle)
        else:
            runs.append(read_csv(p))
    return runs


def read_mcap(path: str, muscle: str | None = None) -> list[Run]:
    """The runs of one recording: one per muscle state topic (or only `muscle`)."""
    from pamd.io import files

    try:
        info = files.inspect(path)
    except RecordingError as exc:
        raise ModelError(str(exc)) from None
    if not info["finalised"]:
        raise ModelError(f"{path}: unfinished recording; run `pamd recover {path}` first")
    meta = info["metadata"]
    loads = {k: _float_or_none(v) for k, v in meta.get("pamd.loads", {}).items()}
    topics = [c["topic"] for c in info["channels"]]
    state_topics = {t.rsplit("/", 1)[1]: t for t in topics if "/state/" in t}
    if muscle is not None:
        if muscle not in state_topics:
            raise ModelError(f"{path}: no muscle {muscle!r} recorded (muscles: "
                             f"{', '.join(state_topics) or 'none'})")
        state_topics = {muscle: state_topics[muscle]}
    if not state_topics:
        raise ModelError(f"{path}: no /pamd/<rig>/state/<muscle> topic in this recording")
    wanted = {t: m for m, t in state_topics.items()}
    rows: dict[str, list[list[Any]]] = {t: [] for t in wanted}
    cols: dict[str, list[str]] = {}
    loop_rows: list[list[Any]] = []
    loop_cols: list[str] = []
    events: list[tuple[float, str, dict[str, Any]]] = []
    dec = files.Decoder()
    try:
        for ch, schema, msg in files.iter_messages(path):
            topic = ch.topic
            if topic in rows:
                if topic not in cols:
                    cols[topic] = dec.columns(ch, schema) or []
                row = dec.decode(ch, schema, msg.data)
                if row is not None:
                    rows[topic].append(row)
            elif topic.endswith("/loop"):
                if not loop_cols:
                    loop_cols = dec.columns(ch, schema) or []
                row = dec.decode(ch, schema, msg.data)
                if row is not None:
                    loop_rows.append(row)
            elif topic.endswith("/events"):
                try:
                    ev = json.loads(msg.data)
                except ValueError:
                    continue
                if isinstance(ev, dict):
                    events.append((float(ev.get("t_s") or 0.0), str(ev.get("kind")),
                                   ev.get("data") or {}))
    except RecordingError as exc:
        raise ModelError(str(exc)) from None
    state_by_tick: dict[int, float] = {}
    if loop_cols and "state" in loop_cols and "tick" in loop_cols:
        it, ist = loop_cols.index("tick"), loop_cols.index("state")
        state_by_tick = {int(r[it]): float(r[ist]) for r in loop_rows}
    runs = []
    for topic, m in wanted.items():
        names = cols.get(topic, [])
        data = rows[topic]
        if not data:
            raise ModelError(f"{path}: topic {topic} holds no messages")
        arr = np.array(data, dtype=np.float64)
        columns = {n: arr[:, i] for i, n in enumerate(names)}
        if "t_s" not in columns:
            raise ModelError(f"{path}: topic {topic} has no t_s field")
        if state_by_tick and "tick" in columns:
            columns["state"] = np.array([state_by_tick.get(int(k), math.nan)
                                         for k in columns["tick"]])
        muscle_events = [e for e in events
                         if e[2].get("args", {}).get("muscle") in (None, m)]
        runs.append(Run(source=path, muscle=m, t_s=columns["t_s"], columns=columns,
                        load_kg=loads.get(m), events=muscle_events,
                        meta={"rig_id": meta.get("pamd", {}).get("rig_id"),
                              "rate_hz": _float_or_none(meta.get("pamd", {}).get("rate_hz"))}))
    return runs


def read_csv(path: str) -> Run:
    """A CSV file with a header row of column names (case-insensitive; units in the
    names as pamd writes them: force_n, length_mm, pressure_bar, ...) and a time
    column (t_s, time_s, time, t or log_time_ns). A muscle file of `pamd export`
    (<topic>_state_<muscle>.csv) takes each tick's state from the loop file beside it."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            sample = fh.read(4096)
            fh.seek(0)
            try:
                dialect: Any = csv.Sniffer().sniff(sample, delimiters=",;\t")
            except csv.Error:
                dialect = csv.excel
            reader = csv.reader(fh, dialect)
            header = next(reader, None)
            if not header:
                raise ModelError(f"{path}: empty file (no header row)")
            names = [h.strip().lower() for h in header]
            raw = list(reader)
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: cannot read it as a CSV text file ({exc})") from None
    if not raw:
        raise ModelError(f"{path}: a header but no data rows")
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        try:
            columns[name] = np.array([_cell(r, j) for r in raw], dtype=np.float64)
        except ValueError:
            continue  # a text column (events, notes): not usable, not needed
    t = None
    for tname, scale in TIME_COLUMNS:
        if tname in columns:
            t = columns[tname] * scale
            break
    if t is None:
        raise ModelError(f"{path}: no time column (one of "
                         f"{', '.join(n for n, _ in TIME_COLUMNS)}); the velocity and "
                         "the settling time need one")
    if not np.all(np.isfinite(t)):
        raise ModelError(f"{path}: the time column has NaN/inf values")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ModelError(f"{path}: time does not increase at row {k + 2} "
                         f"({t[k]:g} then {t[k + 1]:g} s)")
    load = None
    if "load_kg" in columns and np.all(columns["load_kg"] == columns["load_kg"][0]):
        load = float(columns["load_kg"][0])
    muscle = ""
    base = os.path.basename(path)
    if "_state_" in base and "state" not in columns and "tick" in columns:
        # `pamd export` writes <rig topic>_state_<muscle>.csv beside <rig topic>_loop.csv:
        # the loop file carries the supervisor state of each tick.
        prefix, _, rest = base.rpartition("_state_")
        muscle = rest[:-4] if rest.endswith(".csv") else rest
        loop_path = os.path.join(os.path.dirname(path), prefix + "_loop.csv")
        if os.path.exists(loop_path):
            loop = read_csv(loop_path).columns
            if "tick" in loop and "state" in loop:
                state = dict(zip(loop["tick"].tolist(), loop["state"].tolist(), strict=True))
                columns["state"] = np.array([state.get(k, math.nan)
                                             for k in columns["tick"].tolist()])
    return Run(source=path, muscle=muscle, t_s=t - t[0], columns=columns, load_kg=load)


def _cell(row: list[str], j: int) -> float:
    if j >= len(row):
        return math.nan
    s = row[j].strip()
    if s == "" or s.lower() in ("nan", "null", "none"):
        return math.nan
    return float(s)


def _float_or_none(v: Any) -> float | None:
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


# -- extraction ------------------------------------------------------------------------
def extract(runs: Sequence[Run], options: ExtractOptions | None = None) -> Samples:
    """Training pairs from `runs` (see the module docstring for what is dropped)."""
    o = options or ExtractOptions()
    o.check()
    if o.muscle is not None:
        runs = [r for r in runs if r.muscle in (o.muscle, "")]
    if not runs:
        raise ModelError("no runs to extract from")
    Xs, ys, ts, idx, info = [], [], [], [], []
    for k, run in enumerate(runs):
        X, y, t, counts = _extract_run(run, o)
        Xs.append(X)
        ys.append(y)
        ts.append(t)
        idx.append(np.full(y.size, k, dtype=np.intp))
        info.append({"source": run.source, "muscle": run.muscle, "load_kg": run.load_kg,
                     "duration_s": round(float(run.t_s[-1] - run.t_s[0]), 3),
                     "samples_kept": int(y.size), "dropped": counts})
    X = np.concatenate(Xs)
    y = np.concatenate(ys)
    total = int(y.size)
    if total < o.min_samples:
        detail = "; ".join(f"{r['source']}: {r['samples_kept']} kept, dropped "
                           f"{r['dropped']}" for r in info)
        raise ModelError(f"too few samples: {total} kept after dropping faults, limits and "
                         f"settling (need at least {o.min_samples}); {detail}")
    for j, name in enumerate(o.inputs):
        lo, hi = float(X[:, j].min()), float(X[:, j].max())
        if not hi > lo:
            raise ModelError(f"input {name!r} is constant ({lo:g}) in every kept sample: no "
                             "membership functions can be placed on it; drop the input or "
                             "record data that spans a range")
    if not float(y.max()) > float(y.min()):
        raise ModelError(f"output {o.output!r} is constant ({float(y[0]):g}) in every kept "
                         "sample: nothing to learn")
    return Samples(X=X, y=y, t_s=np.concatenate(ts), run=np.concatenate(idx),
                   inputs=tuple(o.inputs), output=o.output, runs=info, options=o)


def _extract_run(run: Run, o: ExtractOptions) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                         dict[str, int]]:
    c = run.columns
    t = np.asarray(run.t_s, dtype=np.float64)
    n = t.size
    need = [n_ for n_ in o.inputs if n_ != "velocity_mm_s"] + [o.output]
    if "velocity_mm_s" in o.inputs:
        need.append("length_mm")
    missing = [n_ for n_ in dict.fromkeys(need) if n_ not in c]
    if missing:
        have = ", ".join(sorted(c)) or "none"
        raise ModelError(f"{run.label}: missing column(s) {', '.join(missing)} (columns: "
                         f"{have})")
    counts: dict[str, int] = {}
    keep = np.ones(n, dtype=bool)

    def drop(mask: np.ndarray, reason: str) -> None:
        new = mask & keep
        if new.any():
            counts[reason] = counts.get(reason, 0) + int(new.sum())
            keep[new] = False

    state = c.get("state")
    accepted = np.ones(n, dtype=bool)
    if state is not None:
        accepted = state == _RUNNING
        drop(~accepted, "not running (idle, hold, load change, fault, estop)")
    if "flags" in c:
        flags = np.nan_to_num(c["flags"], nan=0.0).astype(np.int64)
        for f in Flag:
            if f & o.drop_flags:
                drop((flags & int(f)) != 0, f"flag {f.name}")
    # Settling: the run's start and the start of each accepted stretch.
    starts = [float(t[0])]
    if state is not None:
        edges = np.flatnonzero(accepted[1:] & ~accepted[:-1]) + 1
        starts += [float(t[i]) for i in edges]
    settle = np.zeros(n, dtype=bool)
    for s in starts:
        settle |= (t >= s) & (t < s + o.settle_s)
    drop(settle, "settling")
    lead = np.zeros(n, dtype=bool)
    for t0, t1 in _lead_ins(run, o.settle_s):
        lead |= (t >= t0) & (t < t1)
    drop(lead, "lead-in ramp")
    # The velocity at full rate, before decimation (the tick's filter).
    cols = dict(c)
    if "velocity_mm_s" in o.inputs:
        length = c["length_mm"]
        bad = ~np.isfinite(length)
        if bad.any():  # hold the last reading through a hole so the filter can run on
            drop(bad, "length NaN (velocity undefined)")
            good = np.flatnonzero(~bad)
            if good.size == 0:
                raise ModelError(f"{run.label}: column 'length_mm' has no finite value")
            pos = np.maximum.accumulate(np.where(bad, 0, np.arange(n)))
            length = length[pos]
            length[: good[0]] = length[good[0]]
        cols["velocity_mm_s"] = np.array(filtered_velocity(t, length, o.velocity_window_s))
    # NaN/inf in a sample that is neither flagged nor outside RUNNING: refused.
    kept_idx = np.flatnonzero(keep)
    for name in dict.fromkeys([*o.inputs, o.output]):
        col = cols[name][kept_idx]
        bad = ~np.isfinite(col)
        if bad.any():
            first_t = float(t[kept_idx[np.flatnonzero(bad)[0]]])
            raise ModelError(f"{run.label}: column {name!r} has {int(bad.sum())} NaN/inf "
                             f"value(s) among the samples kept for training, first at "
                             f"t = {first_t:.3f} s; repair or cut that part of the data")
    # Decimate: the first kept sample in each 1/rate_hz bin.
    bins = np.floor(t * o.rate_hz).astype(np.int64)
    if kept_idx.size:
        b = bins[kept_idx]
        first = np.ones(kept_idx.size, dtype=bool)
        first[1:] = b[1:] != b[:-1]
        counts["decimated"] = int((~first).sum())
        kept_idx = kept_idx[first]
    X = np.column_stack([cols[n_][kept_idx] for n_ in o.inputs]) if kept_idx.size else \
        np.empty((0, len(o.inputs)))
    y = cols[o.output][kept_idx]
    return X, y, t[kept_idx], counts


def _lead_ins(run: Run, settle_s: float) -> list[tuple[float, float]]:
    """(start, end) of each profile's lead-in ramp plus `settle_s`, from the profile
    and setpoint commands on the events topic (MCAP only)."""
    out = []
    sp = run.columns.get("setpoint_bar")
    for t0, kind, data in run.events:
        if kind != "command" or data.get("verb") not in _PROFILE_VERBS or not data.get("ok"):
            continue
        args = data.get("args") or {}
        lead_s = 0.0
        if data.get("verb") == "profile" and sp is not None:
            start = _profile_start(args)
            rate = float(args.get("lead_in_bar_per_s") or 1.0)
            i = int(np.searchsorted(run.t_s, t0))
            if start is not None and 0 <= i < sp.size and math.isfinite(sp[i]):
                lead_s = abs(start - float(sp[i])) / rate
        out.append((t0, t0 + lead_s + settle_s))
    return out


def _profile_start(args: dict[str, Any]) -> float | None:
    kind = args.get("kind")
    lo, hi = args.get("min_bar"), args.get("max_bar")
    if kind == "sine" and lo is not None and hi is not None:
        return 0.5 * (float(lo) + float(hi))
    if kind in ("triangle", "step") and lo is not None:
        return float(lo)
    if kind == "constant":
        v = args.get("to_bar", lo)
        return None if v is None else float(v)
    return None


def load_samples(paths: Sequence[str], options: ExtractOptions | None = None) -> Samples:
    """`read_runs` then `extract`."""
    o = options or ExtractOptions()
    return extract(read_runs(paths, o.muscle), o)


# -- splitting -------------------------------------------------------------------------
@dataclass
class Split:
    train: Samples
    validation: Samples | None
    test: Samples | None
    how: dict[str, Any]


def split(samples: Samples, val_fraction: float = 0.2, test_fraction: float = 0.0, *,
          by: str = "block", block_s: float = 10.0, seed: int = 0) -> Split:
    """Training / validation / test sets of whole time blocks (`by="block"`, blocks of
    `block_s` within each run) or whole runs (`by="run"`), chosen reproducibly for
    `seed`. A fraction of 0 gives no such set. No block or run is in two sets, so a
    sample's neighbours (which the velocity filter and the slow sweep make nearly
    equal to it) never sit on the other side of the split."""
    for name, f in (("validation", val_fraction), ("test", test_fraction)):
        if not 0.0 <= f < 1.0:
            raise ModelError(f"the {name} fraction must be in [0, 1), got {f}")
    if val_fraction + test_fraction >= 1.0:
        raise ModelError("validation and test fractions leave nothing to train on")
    if by == "run":
        units = samples.run.copy()
    elif by == "block":
        if not block_s > 0:
            raise ModelError("block_s must be > 0")
        units = np.zeros(len(samples), dtype=np.int64)
        next_id = 0
        for r in np.unique(samples.run):
            sel = samples.run == r
            t = samples.t_s[sel]
            b = np.floor((t - t[0]) / block_s).astype(np.int64)
            units[sel] = b + next_id
            next_id += int(b.max()) + 1
    else:
        raise ModelError(f"split by {by!r}? use 'block' or 'run'")
    ids = np.unique(units)
    n = ids.size
    n_test = _count(test_fraction, n)
    n_val = _count(val_fraction, n)
    if n_test + n_val >= n:
        what = "runs" if by == "run" else f"{block_s:g} s blocks"
        raise ModelError(f"only {n} {what} in the data: too few to hold out "
                         f"{n_val} for validation and {n_test} for test and still train; "
                         "record more, use smaller blocks or lower the fractions")
    order = np.random.default_rng(seed).permutation(ids)
    test_ids, val_ids = order[:n_test], order[n_test:n_test + n_val]
    in_test = np.isin(units, test_ids)
    in_val = np.isin(units, val_ids)
    train = samples.subset(~in_test & ~in_val)
    how = {"by": by, "block_s": block_s if by == "block" else None, "seed": seed,
           "units": int(n), "validation_units": int(n_val), "test_units": int(n_test),
           "train_samples": len(train), "validation_samples": int(in_val.sum()),
           "test_samples": int(in_test.sum())}
    return Split(train, samples.subset(in_val) if n_val else None,
                 samples.subset(in_test) if n_test else None, how)


def _count(fraction: float, n: int) -> int:
    if fraction <= 0:
        return 0
    return max(1, int(round(fraction * n)))


def derived_inputs(inputs: Sequence[str],
                   window_s: float = MODEL_VELOCITY_WINDOW_S) -> dict[str, Any]:
    """The model file's `derived_inputs` entry for these inputs."""
    return {"velocity_mm_s": derivation(window_s)} if "velocity_mm_s" in inputs else {}

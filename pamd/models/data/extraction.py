"""Training pairs for the inverse model, taken from recorded runs.

Role: from `Run`s (`pamd.models.data.recordings`), keep the samples that show the
muscle's steady behaviour and return inputs X (force, length or contraction,
optionally velocity) and the measured output y (pressure) as `Samples`, with each
run's provenance; `pamd.models.data.splitting` then cuts them into training / validation /
test sets.

What is dropped, per run (counted per reason in the provenance):

* faults and other states: with a state column (MCAP: the loop topic) only RUNNING
  samples are kept (IDLE holds, HOLD, LOAD_CHANGE, FAULT, ESTOP, STARTING are not
  the sweep);
* flagged samples: stale signals, soft limits (pressure, contraction, pretension),
  PID saturation, open exhaust, tracking alarms, a length without its datum
  (`pamd.models.data.samples.DROP_FLAGS`); on on/off valves (the recording's config
  says `actuation: onoff`, or for a table that carries no config, the options'
  `actuation`) the exhaust's PWM pulses are the control itself, as the inflate
  valve's are, and are kept (`pamd.wire.declare.fields.PWM_VALVE_FLAGS`);
* settling transients: the first `settle_s` of each run and of each stretch of
  accepted state, and, in MCAP files, each profile's lead-in ramp (computed from the
  profile command recorded on the events topic) plus `settle_s`.

The velocity input is computed from the length at the recording's full rate with
`pamd.models.velocity.filtered_velocity`, the very function the control tick uses
(with the model's window, stored in the model file and used by the tick), and only
then are the samples decimated to `rate_hz` (1 kHz is far more than a model
of a 0.05 Hz sweep needs). Seed 001's change of length (`delta_length_mm`) is the
length's change over one sample period of the model, 1 / rate_hz: L(t) - L(t - 1 /
rate_hz), the earlier length read off the full-rate record (linear between its
samples), so a dropped sample between two kept ones does not stretch it; in a table
of samples (no time column) the change from the previous row. Where there is no
earlier length (a run's first sample period) the sample is dropped.

Bad data is refused with `ModelError` naming file, column and problem: a missing
column, NaN/inf among the kept samples, a constant input, too few samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pamd.models.data.recordings import read_runs
from pamd.models.data.samples import FROM_LENGTH, ExtractOptions, Run, Samples
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S, derivation, filtered_velocity
from pamd.profiles import SHAPES, ProfileSpec
from pamd.wire.declare.fields import PWM_VALVE_FLAGS
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError
from pamd.wire.tick import Flag, State

_RUNNING = int(State.RUNNING)
_PROFILE_VERBS = ("profile", "setpoint")


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
        actuation = _actuation(run, o)
        X, y, t, counts = _extract_run(run, o, actuation)
        Xs.append(X)
        ys.append(y)
        ts.append(t)
        idx.append(np.full(y.size, k, dtype=np.intp))
        info.append({"source": run.source, "muscle": run.muscle, "load_kg": run.load_kg,
                     "actuation": actuation,
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


def _actuation(run: Run, o: ExtractOptions) -> str | None:
    """The run's muscle's `actuation`: as its file's config says (pamd's recordings and
    exports: the file knows its rig), else as the options say (a lab's table), else None
    (a regulator's). Each run's provenance says which it was."""
    said = run.meta.get("actuation")
    return said if isinstance(said, str) else o.actuation


class _Kept:
    """Which of a run's samples are kept, and how many were dropped for each reason (in
    the order the reasons first dropped one)."""

    def __init__(self, n: int) -> None:
        self.mask = np.ones(n, dtype=bool)
        self.counts: dict[str, int] = {}

    def drop(self, mask: np.ndarray, reason: str) -> None:
        """Drop the kept samples `mask` selects, counted under `reason`."""
        new = mask & self.mask
        if new.any():
            self.counts[reason] = self.counts.get(reason, 0) + int(new.sum())
            self.mask[new] = False


def _extract_run(run: Run, o: ExtractOptions, actuation: str | None,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    c = run.columns
    t = np.asarray(run.t_s, dtype=np.float64)
    _check_columns(run, o)
    kept = _Kept(t.size)
    accepted = _drop_state_and_flags(c, o, actuation, kept)
    timeless = run.meta.get("time") == "rows"  # a table of samples (pamd.client.training_tables)
    _drop_settling(run, o, t, accepted, timeless, kept)
    # The velocity (the tick's filter) and the change of length at full rate, before
    # decimation.
    cols = _with_length_inputs(run, o, t, timeless, kept)
    kept_idx = np.flatnonzero(kept.mask)
    _refuse_nonfinite(run, o, cols, kept_idx, t)
    # Decimate: the first kept sample in each 1/rate_hz bin.
    bins = np.floor(t * o.rate_hz).astype(np.int64)
    if kept_idx.size and not timeless:
        b = bins[kept_idx]
        first = np.ones(kept_idx.size, dtype=bool)
        first[1:] = b[1:] != b[:-1]
        kept.counts["decimated"] = int((~first).sum())
        kept_idx = kept_idx[first]
    X = np.column_stack([cols[n_][kept_idx] for n_ in o.inputs]) if kept_idx.size else \
        np.empty((0, len(o.inputs)))
    y = cols[o.output][kept_idx]
    return X, y, t[kept_idx], kept.counts


def _check_columns(run: Run, o: ExtractOptions) -> None:
    """The run has the columns the options need (the length, for an input computed
    from it)."""
    need = [n_ for n_ in o.inputs if n_ not in FROM_LENGTH] + [o.output]
    if any(n_ in FROM_LENGTH for n_ in o.inputs):
        need.append("length_mm")
    missing = [n_ for n_ in dict.fromkeys(need) if n_ not in run.columns]
    if missing:
        have = ", ".join(sorted(run.columns)) or "none"
        raise ModelError(f"{run.label}: missing column(s) {', '.join(missing)} (columns: "
                         f"{have})")


def _drop_state_and_flags(c: dict[str, np.ndarray], o: ExtractOptions, actuation: str | None,
                          kept: _Kept) -> np.ndarray:
    """Drop the samples outside RUNNING and those with a flag the options drop (an
    on/off muscle's valve flags kept: they are its actuation); the samples in RUNNING
    returned (all, without a state column)."""
    state = c.get("state")
    accepted = np.ones(kept.mask.size, dtype=bool)
    if state is not None:
        accepted = state == _RUNNING
        kept.drop(~accepted, "not running (idle, hold, load change, fault, estop)")
    if "flags" in c:
        flags = np.nan_to_num(c["flags"], nan=0.0).astype(np.int64)
        dropped = o.drop_flags
        if actuation == "onoff":
            dropped &= ~int(PWM_VALVE_FLAGS)
        for f in Flag:
            if f & dropped:
                kept.drop((flags & int(f)) != 0, f"flag {f.name}")
    return accepted


def _drop_settling(run: Run, o: ExtractOptions, t: np.ndarray, accepted: np.ndarray,
                   timeless: bool, kept: _Kept) -> None:
    """Drop `settle_s` after the run's start and the start of each accepted stretch (a
    table of samples, `timeless`: none), and each profile's lead-in ramp."""
    starts = [float(t[0])]
    if run.columns.get("state") is not None:
        edges = np.flatnonzero(accepted[1:] & ~accepted[:-1]) + 1
        starts += [float(t[i]) for i in edges]
    settle = np.zeros(t.size, dtype=bool)
    for s in [] if timeless else starts:
        settle |= (t >= s) & (t < s + o.settle_s)
    kept.drop(settle, "settling")
    lead = np.zeros(t.size, dtype=bool)
    for t0, t1 in _lead_ins(run, o.settle_s):
        lead |= (t >= t0) & (t < t1)
    kept.drop(lead, "lead-in ramp")


def _with_length_inputs(run: Run, o: ExtractOptions, t: np.ndarray, timeless: bool,
                        kept: _Kept) -> dict[str, np.ndarray]:
    """The run's columns with the inputs computed from the length (the velocity, the
    change of length) at full rate; a hole in the length held through (its samples
    dropped) so the filter can run on."""
    cols = dict(run.columns)
    if not any(n_ in FROM_LENGTH for n_ in o.inputs):
        return cols
    length = _length_held(run, kept)
    if "velocity_mm_s" in o.inputs:
        cols["velocity_mm_s"] = np.array(filtered_velocity(t, length, o.velocity_window_s))
    if "delta_length_mm" in o.inputs:
        delta = delta_length(t, length, o.rate_hz, timeless)
        kept.drop(~np.isfinite(delta), "first sample period (no change of length yet)")
        cols["delta_length_mm"] = delta
    return cols


def _length_held(run: Run, kept: _Kept) -> np.ndarray:
    """The length, each non-finite reading replaced by the last finite one (the first
    finite one before it) and its sample dropped."""
    length = run.columns["length_mm"]
    bad = ~np.isfinite(length)
    if not bad.any():
        return length
    kept.drop(bad, "length NaN (velocity undefined)")
    good = np.flatnonzero(~bad)
    if good.size == 0:
        raise ModelError(f"{run.label}: column 'length_mm' has no finite value")
    pos = np.maximum.accumulate(np.where(bad, 0, np.arange(kept.mask.size)))
    length = length[pos]
    length[: good[0]] = length[good[0]]
    return length


def _refuse_nonfinite(run: Run, o: ExtractOptions, cols: dict[str, np.ndarray],
                      kept_idx: np.ndarray, t: np.ndarray) -> None:
    """NaN/inf in a sample that is neither flagged nor outside RUNNING: refused (a
    table: at its file row and column)."""
    for name in dict.fromkeys([*o.inputs, o.output]):
        col = cols[name][kept_idx]
        bad = ~np.isfinite(col)
        if not bad.any():
            continue
        at = int(kept_idx[np.flatnonzero(bad)[0]])
        if "row_offset" in run.meta:  # a table: its file row and column
            raise ModelError(f"{run.source}:{at + run.meta['row_offset']}:{name}: "
                             f"{cols[name][at]} in a sample kept for training "
                             f"({int(bad.sum())} NaN/inf value(s) in the column); "
                             "repair or cut that row")
        first_t = float(t[at])
        raise ModelError(f"{run.label}: column {name!r} has {int(bad.sum())} NaN/inf "
                         f"value(s) among the samples kept for training, first at "
                         f"t = {first_t:.3f} s; repair or cut that part of the data")


def delta_length(t_s: np.ndarray, length_mm: np.ndarray, rate_hz: float,
                 rows: bool = False) -> np.ndarray:
    """Seed 001's change of length (mm): L(t) - L(t - 1 / rate_hz), the earlier length
    linear between the recorded samples; with `rows` (a table of samples, no time)
    the change from the previous row. NaN where there is no earlier length."""
    if rows:
        out = np.empty_like(length_mm)
        out[0] = np.nan
        out[1:] = np.diff(length_mm)
        return out
    before = np.interp(t_s - 1.0 / rate_hz, t_s, length_mm, left=np.nan)
    out_t: np.ndarray = length_mm - before
    return out_t


def _lead_ins(run: Run, settle_s: float) -> list[tuple[float, float]]:
    """(start, end) of each profile's lead-in ramp plus `settle_s`, from the profile
    and setpoint commands on the events topic (MCAP only)."""
    out = []
    setpoint = run.columns.get("setpoint_bar")
    for t0, kind, data in run.events:
        if kind != "command" or data.get("verb") not in _PROFILE_VERBS or not data.get("ok"):
            continue
        args = data.get("args") or {}
        lead_s = 0.0
        if data.get("verb") == "profile" and setpoint is not None:
            start = _profile_start(args)
            rate = float(args.get("lead_in_bar_per_s") or 1.0)
            i = int(np.searchsorted(run.t_s, t0))
            if start is not None and 0 <= i < setpoint.size and math.isfinite(setpoint[i]):
                lead_s = abs(start - float(setpoint[i])) / rate
        out.append((t0, t0 + lead_s + settle_s))
    return out


def _profile_start(args: JsonObject) -> float | None:
    """Where a recorded profile command's shape starts (its lead-in's end), by the shape's
    own rule (`pamd.profiles`); None where the record does not say (a ramp
    starts where it is)."""
    shape = SHAPES.get(str(args.get("shape", args.get("kind"))))  # `kind`: the old key
    if shape is None:
        return None
    try:
        to_bar = args.get("to_bar")
        spec = ProfileSpec(shape_name=shape.name, min_bar=float(args["min_bar"]),
                           max_bar=float(args["max_bar"]),
                           to_bar=None if to_bar is None else float(to_bar))
    except (KeyError, TypeError, ValueError):
        return None
    start = spec.start_value()
    return None if math.isnan(start) else start


def load_samples(paths: Sequence[str], options: ExtractOptions | None = None) -> Samples:
    """`read_runs` then `extract`."""
    o = options or ExtractOptions()
    return extract(read_runs(paths, o.muscle), o)


def derived_inputs(inputs: Sequence[str], window_s: float = MODEL_VELOCITY_WINDOW_S,
                   rate_hz: float = 50.0) -> JsonObject:
    """The model file's `derived_inputs` entry for these inputs."""
    out: JsonObject = {}
    if "velocity_mm_s" in inputs:
        out["velocity_mm_s"] = derivation(window_s)
    if "delta_length_mm" in inputs:
        out["delta_length_mm"] = {
            "derived_from": "length_mm", "unit": "mm", "sample_period_s": 1.0 / rate_hz,
            "method": "L(t) - L(t - sample_period_s), the earlier length linear between "
                      "the recorded samples (a table of samples: the previous row)",
            "function": "pamd.models.data.extraction.delta_length"}
    return out

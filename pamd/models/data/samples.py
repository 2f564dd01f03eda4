"""The data of ANFIS training: one recorded run, what to extract from runs, and the
training pairs with their provenance.

Role: the types that reading (`pamd.models.data.recordings`), extraction
(`pamd.models.data.extraction`) and splitting (`pamd.models.data.splitting`) pass between them,
and the model inputs and outputs they can produce, with units.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from pamd.config.schema import ACTUATIONS
from pamd.models.velocity import MODEL_VELOCITY_WINDOW_S
from pamd.wire.declare.fields import PWM_VALVE_FLAGS
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError
from pamd.wire.tick import Flag

#: Model inputs this module can produce, with units (pressure_bar: a forward model's
#: input, seed 002's F(p, k); the tick feeds none, so such a model cannot drive a muscle).
#: delta_length_mm: seed 001's change of length, the length's change from one sample to
#: the next at the model's sample rate (mm per sample; `pamd.models.data.extraction`);
#: the tick feeds velocity_mm_s instead, so a model of it is judged offline.
INPUT_UNITS: dict[str, str] = {
    "force_n": "N", "length_mm": "mm", "contraction": "", "velocity_mm_s": "mm/s",
    "pressure_bar": "bar", "delta_length_mm": "mm",
}
#: Inputs computed from the length column (before decimation, at the recording's rate).
FROM_LENGTH: tuple[str, ...] = ("velocity_mm_s", "delta_length_mm")
#: Targets (outputs) it can produce (measured signals), with units.
OUTPUT_UNITS: dict[str, str] = {"pressure_bar": "bar", "force_n": "N", "length_mm": "mm",
                                "contraction": ""}

#: Flag bits whose samples are not training data.
DROP_FLAGS = int(Flag.STALE | Flag.SOFT_LIMIT_PRESSURE | Flag.SOFT_LIMIT_CONTRACTION
                 | Flag.PRETENSION_LIMIT | Flag.OUTPUT_SATURATED | Flag.EXHAUST_OPEN
                 | Flag.TRACKING | Flag.NO_LENGTH_DATUM)


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
    events: list[tuple[float, str, JsonObject]] = field(default_factory=list)
    meta: JsonObject = field(default_factory=dict)

    @property
    def label(self) -> str:
        return f"{self.source} [{self.muscle}]" if self.muscle else self.source


@dataclass(frozen=True)
class ExtractOptions:
    """What to extract and what to drop (see `pamd.models.data.extraction`)."""

    inputs: tuple[str, ...] = ("force_n", "length_mm")
    output: str = "pressure_bar"
    muscle: str | None = None  # MCAP: only this muscle (default: every muscle, pooled)
    settle_s: float = 2.0  # dropped at the start of each run, state stretch and lead-in
    rate_hz: float = 50.0  # decimated sample rate
    drop_flags: int = DROP_FLAGS
    velocity_window_s: float = MODEL_VELOCITY_WINDOW_S  # the model's velocity filter
    min_samples: int = 50  # fewer kept samples than this is refused
    #: the muscles' `actuation` where a file does not say (a lab's own CSV or MAT table;
    #: pamd's recordings and exports carry their config): None, a regulator's
    actuation: str | None = None

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
        if self.actuation is not None and self.actuation not in ACTUATIONS:
            raise ModelError(f"unknown actuation {self.actuation!r}; use one of "
                             f"{', '.join(ACTUATIONS)}")


@dataclass
class Samples:
    """Training pairs: X (n x d) in input units, y (n,), each sample's time and run."""

    X: np.ndarray
    y: np.ndarray
    t_s: np.ndarray
    run: np.ndarray  # index into `runs`
    inputs: tuple[str, ...]
    output: str
    runs: list[JsonObject]  # provenance of each run (source, muscle, load, counts)
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

    def provenance(self) -> JsonObject:
        """What the model file says about its data."""
        o = self.options
        loads = sorted({r["load_kg"] for r in self.runs if r.get("load_kg") is not None})
        out: JsonObject = {
            "files": sorted({r["source"] for r in self.runs}),
            "runs": self.runs,
            "loads_kg": loads,
            "samples": len(self),
            "extraction": {
                "settle_s": o.settle_s, "rate_hz": o.rate_hz,
                "drop_flags": [f.name for f in Flag if f & o.drop_flags],
                "kept_on_onoff_valves": [f.name for f in Flag if f & PWM_VALVE_FLAGS],
                "actuation": o.actuation,  # for the files that do not say their own
                "states_kept": ["RUNNING"],
                "lead_in_ramps": "dropped (MCAP profile commands)",
                "velocity_window_s": o.velocity_window_s,
            },
        }
        return out

"""What a model kind declares: the one record (`Kind`) that `pamd train`, `pamd evaluate`,
the feedforward and the docs read, so that a new kind is one module and one line of
`pamd.models.registry`.

Role: a kind module builds one `Kind` (or one per kind it holds) from

* its name, its seed paper and its help line (`summary`);
* its file reader (`from_dict`) and its default inputs (in the paper's order);
* its training options: a frozen dataclass derived from `KindOptions`, each field
  declared with `option(default, help, ...)` (the flag, its parser, its bounds or
  choices); `pamd train` makes one flag per option name (kinds that share a name share
  the flag: it must parse the same way) and `make_options` checks given values;
* its fit (`fit(job) -> Fitted`): the samples, their split, the options, the seed,
  the provenance and a progress callback in one `FitJob`;
* whether online adaptation can update it (`adaptable`), how training reports
  progress (`progress`), what its forward model predicts (`forward`, for the
  ``forward_*`` metrics) and the extra figures `pamd evaluate --plot` draws for
  one model of the kind (`plots`), and what outputs it can be trained for (`outputs`).

How a model evaluates is the model's own (the contract: `predict`, `compile`, and
`stateful`, which makes `pamd evaluate` and the test score run it over whole runs in
time order). This module imports no kind: only the contract and the sample types.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np

from pamd.models.contract import InverseModel
from pamd.models.data.samples import Samples
from pamd.models.data.splitting import Split
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

#: Progress: (epoch or generation, training error, validation error or None).
Progress = Callable[[int, float, float | None], None]


# Any: the default is the field's (any option type) and the result is a dataclass field
def option(default: Any, help: str, *, parse: Callable[[str], Any] | None = None,
           minimum: float | None = None, choices: Sequence[str] | None = None,
           # Any: standing for that value in the class body (dataclasses.field's typing)
           metavar: str | None = None, default_text: str | None = None) -> Any:
    """A training option of a kind (a dataclass field of its `KindOptions`): its default,
    its help line, how `pamd train` parses its flag (default: the default's type), the
    least value it may take or the values it may be, and how help states the default
    (default: the value)."""
    if parse is None and default is None:
        raise TypeError(f"option {help!r}: without a default it needs parse=")
    meta = {"help": help, "parse": parse or type(default), "minimum": minimum,
            "choices": tuple(choices) if choices is not None else None, "metavar": metavar,
            "default_text": default_text if default_text is not None else f"{default:g}"
            if isinstance(default, float) else str(default)}
    return dataclasses.field(default=default, metadata=meta)


@dataclass(frozen=True)
class OptionSpec:
    """One declared option, as `pamd train` and `make_options` see it."""

    name: str
    help: str
    parse: Callable[[str], object]
    default: object
    default_text: str
    minimum: float | None
    choices: tuple[str, ...] | None
    metavar: str | None

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")


@dataclass(frozen=True)
class KindOptions:
    """A kind's training options (none here: a kind with options derives from this and
    declares each with `option`). `check` refuses settings that do not fit the inputs
    before any data is read."""

    def check(self, inputs: Sequence[str]) -> None:
        """ModelError if these options cannot train a model of `inputs`."""


def option_specs(cls: type[KindOptions]) -> tuple[OptionSpec, ...]:
    """The options a `KindOptions` class declares, in declaration order."""
    out = []
    for f in dataclasses.fields(cls):
        m = f.metadata
        if "help" not in m:
            continue
        out.append(OptionSpec(f.name, m["help"], m["parse"], f.default, m["default_text"],
                              m["minimum"], m["choices"], m["metavar"]))
    return tuple(out)


OptionsT = TypeVar("OptionsT", bound=KindOptions)


@dataclass(frozen=True)
class FitJob(Generic[OptionsT]):
    """Everything a kind's fit is given: the samples (in time order, each row's run),
    their split, the kind's options and seed, and what the model file carries."""

    samples: Samples
    parts: Split
    options: OptionsT
    seed: int = 0
    derived_inputs: JsonObject | None = None
    provenance: JsonObject | None = None
    callback: Progress | None = None

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self.samples.inputs)

    @property
    def input_units(self) -> list[str]:
        return list(self.samples.input_units)

    @property
    def train(self) -> tuple[np.ndarray, np.ndarray]:
        """The training rows (X, y)."""
        return self.parts.train.X, self.parts.train.y

    @property
    def validation(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The validation rows (X, y), if the split holds any."""
        va = self.parts.validation
        return (va.X, va.y) if va is not None else None

    def mask(self, subset: Samples) -> np.ndarray:
        """Which rows of `samples` are in `subset` (a part of the split)."""
        return rows_of(self.samples, subset)


@dataclass(frozen=True)
class Fitted:
    """A fit's result: the model, and what `pamd train` says of it after the file name
    (default: "KIND model REPR, N parameters")."""

    model: InverseModel
    summary: str = ""


@dataclass(frozen=True)
class Forward:
    """What a kind's forward model predicts (its ``forward_*`` metrics): a label for
    the report and the unit of its errors."""

    label: str
    unit: str


#: Extra figures of one model: (prefix, model, time axis, measured, predicted, clipped,
#: title) -> the files written.
Plots = Callable[[str, InverseModel, np.ndarray, np.ndarray, np.ndarray, np.ndarray, str],
                 list[str]]


@dataclass(frozen=True)
class Kind(Generic[OptionsT]):
    """One model kind, declared once (see the module doc)."""

    name: str
    seed: str
    summary: str
    from_dict: Callable[[object], InverseModel]
    default_inputs: tuple[str, ...]
    fit: Callable[[FitJob[OptionsT]], Fitted]
    options: type[OptionsT]
    adaptable: bool = False
    #: (steps, unit, error name) of the progress bar, from the options; None: no bar
    progress: Callable[[OptionsT], tuple[int, str, str]] | None = None
    #: how many trainings the fit runs one after another (each `progress` steps long,
    #: its steps counted on from the one before's), from the options; None: one
    starts: Callable[[OptionsT], int] | None = None
    forward: Forward | None = None
    plots: Plots | None = None
    #: the outputs it can be trained to predict (`pamd train --output`)
    outputs: tuple[str, ...] = ("pressure_bar",)

    @property
    def option_specs(self) -> tuple[OptionSpec, ...]:
        return option_specs(self.options)

    def make_options(self,
                     # Any: option values by name (parsed flags, a bench's), checked below
                     given: Mapping[str, Any] | None = None, *,
                     ignore_unknown: bool = False) -> OptionsT:
        """The kind's options: its defaults, with `given` (by option name) checked
        against their bounds and choices. An option this kind does not have is a
        ModelError unless `ignore_unknown` (settings shared across kinds)."""
        specs = {s.name: s for s in self.option_specs}
        values: dict[str, object] = {}
        for name, value in (given or {}).items():
            spec = specs.get(name)
            if spec is None:
                if ignore_unknown:
                    continue
                raise ModelError(f"--{name.replace('_', '-')} is not an option of kind "
                                 f"{self.name} (its options: "
                                 f"{', '.join(s.flag for s in specs.values()) or 'none'})")
            if value is None:
                continue
            if spec.minimum is not None and value < spec.minimum:
                raise ModelError(f"{spec.flag} must be at least {spec.minimum:g} "
                                 f"(got {value})")
            if spec.choices is not None and value not in spec.choices:
                raise ModelError(f"{spec.flag} is one of {', '.join(spec.choices)} "
                                 f"(got {value!r})")
            values[name] = value
        return self.options(**values)

    def help_line(self) -> str:
        """The kind in one line: name, seed and summary."""
        return f"{self.name:<11} seed {self.seed}: {self.summary}"


def rows_of(samples: Samples, subset: Samples) -> np.ndarray:
    """The mask of `samples` rows that are in `subset` (a split of them)."""
    def key(s: Samples) -> np.ndarray:
        return s.run.astype(np.int64) * (1 << 40) + np.round(s.t_s * 1e6).astype(np.int64)

    return np.isin(key(samples), key(subset))

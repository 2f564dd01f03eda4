"""The `model` command's preparation, outside the loop's process: its file read (a
remote command's only by name from `telemetry.models_dir`, within the limits of
`named_files`), parsed, checked against the muscle and timed, all in a short-lived
child process (`offload.run_isolated`); back in the daemon the checked model is
compiled, so the loop only swaps the compiled object in (`Verb.prepare`).

**The tick's budget.** A model whose one evaluation takes more than
`MODEL_TICK_FRACTION` of the loop's period is refused: the child compiles it and times
`TIMING_CALLS` evaluations across its input ranges, `TIMING_RUNS` times, and takes the
best run (the machine's speed, not its momentary load: a busy PC only makes a run
slower). The kinds' own caps (125 ANFIS rules, 24 support vectors...) keep the models
meant for the tick well inside it (a 125-rule ANFIS: about 0.1 ms on a busy 2-core
PC, a tenth of a 1 kHz period).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time

from pamd.config.loader import LoadedConfig, MuscleLimitsResolved, load_config
from pamd.config.schema import MuscleConfig
from pamd.loop.commands.named_files import MODEL_MAX_BYTES, parse_time_limit_s, read_limited
from pamd.loop.commands.offload import run_isolated
from pamd.loop.commands.prepared import PreparedModelArgs
from pamd.loop.control.feedforward import LoadedModel, load_models
from pamd.loop.control.model_check import SOURCES
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused, ModelError
from pamd.wire.verbs.args import MAX_ERROR_CHARS, Command, cap_text

#: Largest share of the loop's period one evaluation of a model may take.
MODEL_TICK_FRACTION = 0.25
TIMING_RUNS, TIMING_CALLS = 5, 40


@dataclasses.dataclass(frozen=True)
class ModelSource:
    """Where a model comes from: a file named in `telemetry.models_dir` (`named`: read
    within its limits, O_NOFOLLOW), the operator's own path, or bytes already read."""

    path: str
    name: str
    named: bool = False
    data: bytes | None = None


def read_model(src: ModelSource, muscle: MuscleConfig, limits: MuscleLimitsResolved,
               period_s: float) -> LoadedModel:
    """In the child: the model read, checked against the muscle and timed against the
    tick's budget; CommandRefused says why not (never quoting the file)."""
    data = src.data
    try:
        if data is None and src.named:
            data = read_limited(src.path, src.name, "model", MODEL_MAX_BYTES).text.encode()
        lm = (LoadedModel.read(src.path, muscle, limits) if data is None
              else LoadedModel.from_bytes(data, src.path, muscle, limits))
    except ModelError as exc:
        raise CommandRefused(cap_text(f"model refused: {exc}", MAX_ERROR_CHARS)) from None
    except OSError as exc:
        raise CommandRefused(f"model refused: {src.name}: {exc.strerror or exc}") from None
    except (RecursionError, UnicodeDecodeError, ValueError) as exc:
        raise CommandRefused(f"model refused: {src.name}: unreadable as a model file "
                             f"({exc.__class__.__name__})") from None
    cost_s = tick_cost_s(lm)
    if cost_s > MODEL_TICK_FRACTION * period_s:
        raise CommandRefused(
            f"model refused: {src.name}: one evaluation takes {cost_s * 1e6:.0f} us, more "
            f"than {MODEL_TICK_FRACTION:.0%} of the loop's {period_s * 1e3:g} ms period "
            f"(timed at load); use a smaller model (fewer rules or support vectors)")
    return lm


def tick_cost_s(lm: LoadedModel) -> float:
    """One evaluation's time, compiled as the tick runs it: the best of TIMING_RUNS
    runs of TIMING_CALLS calls across the inputs' ranges."""
    ff = lm.feedforward()
    lo = [0.0] * len(SOURCES)
    hi = [0.0] * len(SOURCES)
    for v in lm.model.inputs:
        k = SOURCES.index(v.name)
        lo[k], hi[k] = float(v.min), float(v.max)
    points = []
    for i in range(TIMING_CALLS):
        u = (i + 0.5) / TIMING_CALLS
        a = [lo[k] + u * (hi[k] - lo[k]) if math.isfinite(hi[k] - lo[k]) else lo[k]
             for k in range(len(SOURCES))]
        points.append((a[0], a[1], a[2], a[3]))
    best = math.inf
    call = ff.pressure
    for _ in range(TIMING_RUNS):
        t0 = time.thread_time()
        for f, ln, x, vel in points:
            call(f, ln, x, vel)
        best = min(best, (time.thread_time() - t0) / TIMING_CALLS)
    return best


def prepare_model(cmd: Command, cfg: LoadedConfig, data: bytes | None) -> Command:
    """`cmd` with its model loaded (PreparedModelArgs); CommandRefused if it cannot be.
    With `data` the bytes are taken as they are: one read, nothing can change between
    the check and the load. The file is read, parsed, checked and timed in a child
    process; only the checked model comes back, and is compiled here."""
    a = cmd.args
    path = os.path.abspath(os.path.expanduser(a.file))
    return prepare_model_from(cmd, cfg, ModelSource(path, a.file, data=data))


def prepare_model_from(cmd: Command, cfg: LoadedConfig, src: ModelSource) -> Command:
    """`prepare_model` for a model from `src` (a remote command: named in
    `telemetry.models_dir`)."""
    if isinstance(cmd.args, PreparedModelArgs):
        return cmd
    a = cmd.args
    try:
        mcfg = cfg.muscle(a.muscle)
    except KeyError:
        names = ", ".join(m.name for m in cfg.rig.muscles)
        raise CommandRefused(f"no muscle named {a.muscle!r}; muscles: {names}") from None
    lm = run_isolated(read_model, src, mcfg, cfg.limits[a.muscle], cfg.period_s,
                      time_limit_s=parse_time_limit_s(cfg), what=f"model refused: {src.name!r}")
    return dataclasses.replace(cmd, args=PreparedModelArgs(a.muscle, src.path,
                                                           lm.feedforward()))


#: A reload's model files are read within this (no client waits on it; it only must end).
RELOAD_TIME_LIMIT_S = 60.0


def check_models_isolated(cfg: LoadedConfig) -> None:
    """`load_models(cfg)` in a child process, for a reload while the loop runs: the
    same ConfigError (file, line, key) if a `model_file` does not load or fit;
    nothing comes back (the daemon loads them again only if it restarts)."""
    run_isolated(_check_models, cfg, time_limit_s=RELOAD_TIME_LIMIT_S,
                 what=f"{cfg.path}: the model files")


def _check_models(cfg: LoadedConfig) -> None:
    load_models(cfg)


def read_config(path: str, overrides: JsonObject | None) -> LoadedConfig:
    """A reloaded config read, validated and its `model_file`s loaded and checked: the
    ConfigError (file, line, key) of either, or the config."""
    cfg = load_config(path, overrides)
    load_models(cfg)
    return cfg


def read_config_isolated(path: str, overrides: JsonObject | None) -> LoadedConfig:
    """`read_config` in a child process (`offload.run_isolated`), for a reload while
    the loop runs: the YAML's parse, the drivers' option checks and the models' reads
    hold the interpreter lock for a long while on a busy PC; only the checked config
    comes back."""
    return run_isolated(read_config, path, overrides, time_limit_s=RELOAD_TIME_LIMIT_S,
                        what=f"{path}: reading it again")

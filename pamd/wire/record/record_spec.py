"""What one run's recording is: where, how files are cut, what each file states
(picklable: the daemon hands it to the io process at spawn)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

from pamd.wire.declare.jsonsafe import JsonObject


@dataclass(frozen=True)
class RecordSpec:
    """One run's recording: where, how files are cut, and what each file states."""

    dir: str
    run_name: str
    rotate_mb: float | None
    rotate_s: float | None
    chunk_kb: int
    flush_s: float
    compression: str
    started_at: str  # local time of the run's start, for file names
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: tuple[tuple[str, str, bytes], ...] = ()  # (name, media type, data)
    fsize_limit_bytes: int | None = None  # tests: RLIMIT_FSIZE, so writes fail for real
    # Experiment steps: the file of step k (tick field `segment` = k + 1) is named after
    # steps[k]["step"] and states steps[k] as its `pamd.experiment` metadata.
    steps: tuple[JsonObject, ...] = ()
    # The run's files together stop taking ticks past this size (events still go in),
    # said in the file and the summary: the cap of an interactive `pamd run`'s default
    # recording. None: no cap.
    max_mb: float | None = None


class RecordedRun(Protocol):
    """What the recorder needs to know of the run it records (the io process's
    `pamd.iohost.io_spec.IoSpec` is one)."""

    @property
    def rig_id(self) -> str: ...
    @property
    def muscles(self) -> tuple[str, ...]: ...
    @property
    def rate_hz(self) -> float: ...
    @property
    def virtual(self) -> bool: ...
    @property
    def wall0_ns(self) -> int: ...
    @property
    def clock0_s(self) -> float: ...
    @property
    def record(self) -> RecordSpec | None: ...

"""What the daemon tells its io process: a picklable description handed over at
spawn (the io process imports nothing of the daemon's live objects)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pamd.ipc.ring import BlockLayout


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
    steps: tuple[dict[str, Any], ...] = ()


@dataclass(frozen=True)
class IoSpec:
    shm_name: str
    layout: BlockLayout
    rig_id: str
    muscles: tuple[str, ...]
    rate_hz: float
    virtual: bool
    wall0_ns: int  # wall clock (ns since the epoch) at loop-clock time clock0_s
    clock0_s: float
    parent_pid: int
    record: RecordSpec | None
    # Commands the io process sends to the loop at a given tick: (tick, verb, payload).
    # The Zenoh session will be the real source; this one proves the path end to end.
    script: tuple[tuple[int, str, dict], ...] = ()
    # Telemetry and remote commands (pamd.net.spec.NetSpec); None: no Zenoh session.
    net: Any = None
    # The live Foxglove view (pamd.view.spec.ViewerSpec); None: no Foxglove server.
    viewer: Any = None

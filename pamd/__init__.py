"""pamd: the controller daemon for pneumatic artificial muscle test beds.

The Python API (stable; nothing else is promised):

- `open_recording(path_or_collection)`: a recording as numpy arrays or pandas
  DataFrames per muscle, with units, state and mode names, events and metadata
  (`Recording`, `MuscleData`, `Event`, `RecordingIncomplete`).
- `connect(rig=None, endpoint=...)`: a running daemon: `status()`,
  `command(verb, **fields)`, `stream()` of state batches (`RigClient`, `StateBatch`).
- The errors they raise: `PamdError` and its kinds `RecordingError`,
  `CommandRefused`, `NoDaemon`.
"""

from __future__ import annotations

import importlib
import os
from typing import TYPE_CHECKING, Any

# Before anything loads numpy: one BLAS thread. The loop's own numpy calls (the model's
# online adaptation, pamd.control.adapt) are small; a threaded BLAS would only add
# wake-ups and contention on the rig PC's cores. A value set by the user stays.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pamd.version import __version__

__all__ = [
    "CommandRefused", "Event", "MuscleData", "NoDaemon", "PamdError", "Recording",
    "RecordingError", "RecordingIncomplete", "RigClient", "StateBatch", "__version__",
    "connect", "open_recording",
]

if TYPE_CHECKING:
    from pamd.errors import CommandRefused, PamdError, RecordingError
    from pamd.net.zconf import NoDaemon
    from pamd.view.client import RigClient, StateBatch, connect
    from pamd.view.recording import (
        Event,
        MuscleData,
        Recording,
        RecordingIncomplete,
        open_recording,
    )

# Imported on first use: `import pamd` stays cheap for the daemon and its io process.
_WHERE = {
    "open_recording": "pamd.view.recording", "Recording": "pamd.view.recording",
    "MuscleData": "pamd.view.recording", "Event": "pamd.view.recording",
    "RecordingIncomplete": "pamd.view.recording", "connect": "pamd.view.client",
    "RigClient": "pamd.view.client", "StateBatch": "pamd.view.client",
    "PamdError": "pamd.errors", "RecordingError": "pamd.errors",
    "CommandRefused": "pamd.errors", "NoDaemon": "pamd.net.zconf",
}


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'pamd' has no attribute {name!r}")

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)

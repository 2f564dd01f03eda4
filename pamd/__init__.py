"""pamd: the controller daemon for pneumatic artificial muscle test beds.

The Python API (stable; nothing else is promised):

- `open_recording(path_or_collection)`: a recording as numpy arrays or pandas
  DataFrames per muscle, with units, state and mode names, events and metadata
  (`Recording`, `MuscleData`, `Event`, `RecordingIncomplete`).
- `connect(rig=None, endpoint=...)`: a running daemon: `status()`,
  `command(verb, **fields)`, `stream()` of state batches (`RigClient`, `StateBatch`).
- The errors they raise: `PamdError` and its subclasses `RecordingError`,
  `CommandRefused`, `NoDaemon`.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any

# Before anything loads numpy: one BLAS thread. The loop's own numpy calls (the model's
# online adaptation, pamd.loop.control.adapt) are small; a threaded BLAS would only add
# wake-ups and contention on the rig PC's cores. A value set by the user stays.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")



class _SourceDrivers(importlib.abc.MetaPathFinder):
    """`pamd.drivers` of a source tree: the design keeps the drivers at the top level
    (`drivers/`, beside `pamd/`) and the installed package has them as `pamd/drivers`
    (pyproject's package-dir). Imported from a clone (`python -m pamd` in its root,
    where the clone's `pamd/` comes first on the path, even with pamd installed; the
    test suite; an editable install), `pamd/` has no `drivers/`: this finder maps
    `pamd.drivers` to the clone's `drivers/`, and its modules follow from there."""

    def __init__(self, directory: str) -> None:
        self.directory = directory

    def find_spec(self, fullname: str, path: Sequence[str] | None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname != "pamd.drivers":
            return None
        return importlib.util.spec_from_file_location(
            fullname, os.path.join(self.directory, "__init__.py"),
            submodule_search_locations=[self.directory])


def _find_source_drivers() -> None:
    here = os.path.dirname(os.path.abspath(__file__))
    if os.path.isdir(os.path.join(here, "drivers")):
        return  # installed: pamd/drivers is there
    source = os.path.join(os.path.dirname(here), "drivers")
    if os.path.isfile(os.path.join(source, "__init__.py")) and not any(
            isinstance(f, _SourceDrivers) for f in sys.meta_path):
        sys.meta_path.insert(0, _SourceDrivers(source))


_find_source_drivers()


class _OldNames(importlib.abc.MetaPathFinder):
    """The module names pamd had before issue 41's move, found in `pamd._moved` (loaded
    only when a name nothing else found is asked for: last on `sys.meta_path`)."""

    def find_spec(self, fullname: str, path: Sequence[str] | None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if not fullname.startswith("pamd.") or fullname == "pamd._moved":
            return None
        from pamd import _moved

        return _moved.OldNames().find_spec(fullname, path, target)


if not any(isinstance(f, _OldNames) for f in sys.meta_path):
    sys.meta_path.append(_OldNames())

from pamd.wire.version import __version__  # noqa: E402

__all__ = [
    "CommandRefused", "Event", "MuscleData", "NoDaemon", "PamdError", "Recording",
    "RecordingError", "RecordingIncomplete", "RigClient", "StateBatch", "__version__",
    "connect", "open_recording",
]

if TYPE_CHECKING:
    from pamd.client.connect import RigClient, StateBatch, connect
    from pamd.client.recording import (
        Event,
        MuscleData,
        Recording,
        RecordingIncomplete,
        open_recording,
    )
    from pamd.wire.errors import CommandRefused, PamdError, RecordingError
    from pamd.wire.zconf import NoDaemon

# Imported on first use: `import pamd` stays cheap for the daemon and its io process.
_WHERE = {
    "open_recording": "pamd.client.recording", "Recording": "pamd.client.recording",
    "MuscleData": "pamd.client.recording", "Event": "pamd.client.recording",
    "RecordingIncomplete": "pamd.client.recording", "connect": "pamd.client.connect",
    "RigClient": "pamd.client.connect", "StateBatch": "pamd.client.connect",
    "PamdError": "pamd.wire.errors", "RecordingError": "pamd.wire.errors",
    "CommandRefused": "pamd.wire.errors", "NoDaemon": "pamd.wire.zconf",
}


def __getattr__(name: str) -> Any:  # Any: a public name imported on first use (typed above)
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'pamd' has no attribute {name!r}")

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)

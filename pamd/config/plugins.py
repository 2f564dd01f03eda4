"""Entry-point groups: how pamd finds what is installed beside it.

Drivers register in `pamd.drivers` (see `pamd.drivers`). The config engine finds a
driver's options type here without importing the drivers package, so the layers
stay one-way: `pamd.config` names the group, `pamd.drivers` implements it."""

from __future__ import annotations

import functools
import os
import sys
from importlib.metadata import EntryPoint, entry_points

from pamd.wire.errors import DriverError

DRIVERS_GROUP = "pamd.drivers"


def installed(group: str) -> dict[str, EntryPoint]:
    """Name -> entry point, for everything installed in `group`."""
    return dict(_installed(group, _import_path_stamp()))


def _import_path_stamp() -> tuple[tuple[str, int | None], ...]:
    """Each directory of the import path with its modification time: installing,
    upgrading or removing a distribution adds or removes its metadata directory there,
    which changes the stamp (so a driver installed while the daemon runs is found at
    the next config load, as before)."""
    stamp: list[tuple[str, int | None]] = []
    for entry in sys.path:
        try:
            stamp.append((entry, os.stat(entry or ".").st_mtime_ns))
        except OSError:
            stamp.append((entry, None))
    return tuple(stamp)


@functools.lru_cache(maxsize=8)
def _installed(group: str, stamp: tuple[tuple[str, int | None], ...]
               ) -> tuple[tuple[str, EntryPoint], ...]:
    """The entry points of `group` for one import-path stamp: reading every installed
    distribution's metadata costs ~5 ms, paid at each config load and rig build before."""
    return tuple((ep.name, ep) for ep in entry_points(group=group))


def load_driver_entry(type_name: str) -> object:
    """What the `pamd.drivers` entry point `type_name` names, or a DriverError listing
    the installed ones."""
    found = installed(DRIVERS_GROUP)
    if type_name not in found:
        names = ", ".join(sorted(found)) or "none"
        raise DriverError(
            f"no driver of type {type_name!r} is installed (installed: {names}); "
            "check the spelling or install the package that provides it"
        )
    return found[type_name].load()

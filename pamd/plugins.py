"""Entry-point groups: how pamd finds what is installed beside it.

Drivers register in `pamd.drivers` (see `pamd.drivers`). The config engine finds a
driver's options type here without importing the drivers package, so the layers
stay one-way: `pamd.config` names the group, `pamd.drivers` implements it."""

from __future__ import annotations

from importlib.metadata import EntryPoint, entry_points

from pamd.errors import DriverError

DRIVERS_GROUP = "pamd.drivers"


def installed(group: str) -> dict[str, EntryPoint]:
    """Name -> entry point, for everything installed in `group`."""
    return {ep.name: ep for ep in entry_points(group=group)}


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

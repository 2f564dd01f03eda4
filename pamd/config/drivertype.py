"""What the config needs of an installed driver class (`pamd.drivers.Driver`), as a
Protocol: the config builds a driver's options and reads its channels before any
driver is opened (pamd.config.loader, pamd.config.chain_rules)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import ClassVar, Protocol, cast, runtime_checkable

from pamd.config.plugins import load_driver_entry
from pamd.muscle_type import MuscleType
from pamd.wire.errors import DriverError


class DriverType(Protocol):
    """What the config needs of an installed driver class (`pamd.drivers.Driver`):
    its options type, and its channels as those options define them."""

    options_type: ClassVar[type]

    def __call__(self, name: str, options: object) -> _HasChannels: ...  # its options type


@runtime_checkable
class BindsMuscleTypes(Protocol):
    """A driver class that simulates muscles (`pamd.drivers.sim`): its options with
    each simulated muscle's type settled from the rig's muscles (`types`: the channel
    a rig muscle reads -> that muscle's type; `base_dir`: the config file's directory,
    for files the options name)."""

    def bind_muscle_types(self, options: object, types: Mapping[str, MuscleType],
                          base_dir: str) -> object: ...


class _HasChannels(Protocol):
    def channels(self) -> Sequence[_ChannelLike]: ...


class _ChannelLike(Protocol):
    @property
    def name(self) -> str: ...

    @property
    def direction(self) -> str: ...

    @property
    def digital(self) -> bool: ...


def driver_type(type_name: str) -> DriverType:
    """The driver class installed under `type_name` (the `pamd.drivers` entry points)."""
    found = load_driver_entry(type_name)
    if not (isinstance(found, type) and hasattr(found, "options_type")
            and hasattr(found, "channels")):
        raise DriverError(f"entry point {type_name!r} does not name a pamd Driver class")
    return cast(DriverType, found)

"""What the live Foxglove view of a run is (`ViewerSpec`, picklable, handed to the io
process at spawn) and how the config and `pamd run --foxglove` decide it (`resolve`).
Light on purpose: the loop's process imports this, never the server (`live`)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pamd.errors import ConfigError, ConfigIssue

if TYPE_CHECKING:  # a type only: the io process unpickles a ViewerSpec without the config
    from pamd.config.loader import LoadedConfig

DEFAULT_LISTEN = "127.0.0.1:8765"
_LISTEN = re.compile(r"^(?:\[(?P<v6>[0-9a-fA-F:.]+)\]|(?P<host>[A-Za-z0-9.\-]+)):(?P<port>\d+)$")


def parse_listen(text: str) -> tuple[str, int]:
    """`HOST:PORT` (IPv6 as `[::1]:8765`) -> (host, port); ValueError saying why not."""
    m = _LISTEN.match(text.strip())
    port = int(m.group("port")) if m else -1
    if m is None or not 0 < port < 65536:
        raise ValueError(f"{text!r} is not HOST:PORT (e.g. {DEFAULT_LISTEN}, "
                         "0.0.0.0:8765 for the lab network)")
    return m.group("v6") or m.group("host"), port


@dataclass(frozen=True)
class ViewerSpec:
    """What the io process serves (picklable, handed over at spawn)."""

    host: str
    port: int
    rig_id: str
    muscles: tuple[str, ...]
    every_ticks: int  # one state message per muscle every this many ticks

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"


def resolve(cfg: LoadedConfig, foxglove: str | None) -> ViewerSpec | None:
    """The viewer of this run, or None. `foxglove`: None: as `telemetry.foxglove`
    says; "default": on at `telemetry.foxglove.listen`; "HOST:PORT": on there. A bad
    listen address is a ConfigError before anything starts."""
    fc = cfg.rig.telemetry.foxglove
    if foxglove is None and not fc.enabled:
        return None
    listen = fc.listen if foxglove in (None, "default") else foxglove
    try:
        host, port = parse_listen(listen)
    except ValueError as exc:
        where = "telemetry.foxglove.listen" if foxglove in (None, "default") else "--foxglove"
        raise ConfigError([ConfigIssue(cfg.path, None, where, "HOST:PORT", str(exc))]) from None
    rate = cfg.rig.loop.rate_hz
    return ViewerSpec(host=host, port=port, rig_id=cfg.rig.rig_id,
                      muscles=tuple(m.name for m in cfg.rig.muscles),
                      every_ticks=max(1, round(rate / cfg.rig.telemetry.rate_hz)))

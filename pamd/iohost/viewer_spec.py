"""What the live Foxglove view of a run is (`ViewerSpec`, picklable, handed to the io
process at spawn) and how the config and `pamd run --foxglove` decide it (`resolve`).
Light on purpose: the loop's process imports this, never the server (`live`)."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from pamd.wire.errors import ConfigError, ConfigIssue

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
    # TLS (telemetry.foxglove.tls_cert, tls_key): the server's PEM certificate chain and
    # PKCS#8 key, read in the daemon; with them the server takes wss:// only
    tls_cert: bytes | None = None
    tls_key: bytes | None = field(default=None, repr=False)

    @property
    def tls(self) -> bool:
        return self.tls_cert is not None

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{'wss' if self.tls else 'ws'}://{host}:{self.port}"


def resolve(cfg: LoadedConfig, foxglove: str | None) -> ViewerSpec | None:
    """The viewer of this run, or None. `foxglove`: None: as `telemetry.foxglove`
    says; "default": on at `telemetry.foxglove.listen`; "HOST:PORT": on there. A bad
    listen address, certificate or key is a ConfigError before anything starts. (Whether
    it may serve beyond loopback is the daemon's to judge: pamd.daemon.host.resolve.)"""
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
    cert, key = _tls(cfg)
    return ViewerSpec(host=host, port=port, rig_id=cfg.rig.rig_id,
                      muscles=tuple(m.name for m in cfg.rig.muscles),
                      every_ticks=max(1, round(rate / cfg.rig.telemetry.rate_hz)),
                      tls_cert=cert, tls_key=key)


#: what the foxglove-sdk's server takes: a PEM certificate (chain) and a PKCS#8 key
_PEM = {"tls_cert": (b"-----BEGIN CERTIFICATE-----", "a PEM certificate"),
        "tls_key": (b"-----BEGIN PRIVATE KEY-----", "a PEM PKCS#8 private key (from an "
                    "RSA or EC key: openssl pkcs8 -topk8 -nocrypt -in KEY -out KEY8)")}


def _tls(cfg: LoadedConfig) -> tuple[bytes | None, bytes | None]:
    """The live view's certificate and key (`telemetry.foxglove.tls_cert`, `tls_key`,
    relative to the config file), read and checked here: a missing or wrong file is a
    ConfigError naming the key before anything starts."""
    fc = cfg.rig.telemetry.foxglove
    given = {"tls_cert": fc.tls_cert, "tls_key": fc.tls_key}
    if not any(given.values()):
        return None, None
    base = os.path.dirname(os.path.abspath(cfg.path))
    out: dict[str, bytes] = {}
    issues = []
    for name, rel in given.items():
        key, (head, what) = f"telemetry.foxglove.{name}", _PEM[name]
        if rel is None:
            other = "tls_key" if name == "tls_cert" else "tls_cert"
            issues.append(ConfigIssue(cfg.path, None, key, f"{what}, with {other}", "none"))
            continue
        path = os.path.join(base, os.path.expanduser(rel))
        try:
            with open(path, "rb") as fh:
                data = fh.read(1 << 20)
        except OSError as exc:
            issues.append(ConfigIssue(cfg.path, None, key, f"{what} file",
                                      f"{path}: {exc.strerror or exc}"))
            continue
        if head not in data:
            issues.append(ConfigIssue(cfg.path, None, key, what, f"{path}: none in it"))
        out[name] = data
    if issues:
        raise ConfigError(issues)
    return out["tls_cert"], out["tls_key"]

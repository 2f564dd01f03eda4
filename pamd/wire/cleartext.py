"""What pamd puts on the network in clear: one rule and one set of words for every
socket it opens (the daemon's Zenoh session listening or connecting, `pamd router`,
the Foxglove live view).

The rule: a plain (unencrypted) link whose far end can be another machine carries
what crosses it readable by anyone on the path (state, status, the command stream;
commands are signed per command so they cannot be replayed or forged, but they and
everything else can be read). So such a link is refused before anything starts,
unless the operator says it on purpose (`--allow-cleartext`,
`telemetry.allow_cleartext: true`); allowed, it is warned at start and in every
status. Loopback (127.0.0.0/8, ::1, localhost) never leaves the machine; TLS (Zenoh's
`tls/` and `quic/`, the live view's `wss://` with `telemetry.foxglove.tls_cert`)
encrypts. Any other address is beyond loopback: 0.0.0.0 and :: are every interface,
a LAN address or a host name another machine.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from pamd.wire.errors import ConfigError, ConfigIssue
from pamd.wire.zconf import is_loopback_host

__all__ = ["DAEMON_FLAG", "ROUTER_FLAG", "Exposure", "is_loopback_host", "judge"]

#: how to say it on purpose, for the daemon (`pamd run`) and the router
DAEMON_FLAG = "pamd run --allow-cleartext, or telemetry.allow_cleartext: true"
ROUTER_FLAG = "pamd router --allow-cleartext"


@dataclass(frozen=True)
class Exposure:
    """One link in clear beyond loopback and where it was configured."""

    role: str  # what opens it: "the Zenoh session listens on", "... connects to", ...
    endpoint: str
    carries: str  # what crosses it: "state, status and signed commands", ...
    tls: str  # how to encrypt it instead
    file: str  # where it was set: a file, or the flag that set it
    line: int | None
    key: str


def judge(exposures: Sequence[Exposure], allowed: bool, flag: str) -> tuple[str, ...]:
    """Links in clear beyond loopback: refused (a ConfigError naming each, where it was
    set and how to say it on purpose) unless `allowed`; allowed, the warnings the start
    and every status say."""
    if not exposures:
        return ()
    if not allowed:
        raise ConfigError([ConfigIssue(
            e.file, e.line, e.key, f"loopback or TLS ({e.tls})",
            f"{e.role} {e.endpoint} beyond loopback without TLS ({e.carries} readable on "
            f"the network); to run so anyway, say it: {flag}") for e in exposures])
    return tuple(f"{e.role} {e.endpoint} beyond loopback WITHOUT TLS (allowed on purpose: "
                 f"{flag}): {e.carries} can be read on the network"
                 for e in exposures)

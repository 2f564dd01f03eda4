"""Zenoh configs for the daemon, the CLI clients and the router, secure by default.

Zenoh's built-in defaults scout by UDP multicast and gossip, which leaves this
machine; every config built here turns both off unless the given file turns them on
explicitly, and names its endpoints. Without a file the daemon is a peer listening
on `telemetry.listen` only (default `tcp/127.0.0.1:7447`) and clients connect there.

Configs travel to the io process as JSON text (`str(zenoh.Config)`), checked here in
the daemon's main process so a bad file is refused before anything starts.
"""

from __future__ import annotations

import json
import os
from typing import Any, Protocol, TypeVar

from pamd.errors import ConfigError, ConfigIssue, PamdError
from pamd.net.tlsprobe import diagnose, listen_error

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
#: client sessions a daemon's own endpoint takes at once (each costs the io process
#: some 170 kB while connected): memory bounded, whatever clients do
MAX_SESSIONS = 100
#: the largest message a client may send it (Zenoh's default is 1 GiB, held whole in
#: the io process while it is reassembled); a command's JSON is refused above 64 KiB
#: anyway, and an estop or stop up to this size still acts
MAX_MESSAGE_BYTES = 4 << 20
# Zenoh's shared-memory transport stays off: with it, the first local subscriber made
# the io process map a 16 MiB pool it kept (+28 MB RSS for 50 clients, never returned)
SCOUTING_KEYS = ("scouting/multicast/enabled", "scouting/gossip/enabled")


class ZenohConfig(Protocol):
    """What is read and set here of a `zenoh.Config`."""

    def get_json(self, key: str) -> Any: ...
    def insert_json5(self, key: str, value: str) -> Any: ...


_Config = TypeVar("_Config", bound=ZenohConfig)


class NoDaemon(PamdError):
    """No daemon (or router) answers where the client looked."""

    exit_code = 7


def _zenoh() -> Any:
    import zenoh

    return zenoh


def _issue(file: str, expected: str, found: str) -> ConfigError:
    return ConfigError([ConfigIssue(file, None, "", expected, found)])


def load_file(path: str) -> Any:
    """A Zenoh config file (JSON5), checked by Zenoh itself."""
    zenoh = _zenoh()
    if not os.path.isfile(path):
        raise _issue(path, "a readable Zenoh config file (JSON5)", "no such file")
    try:
        return zenoh.Config.from_file(path)
    except Exception as exc:  # zenoh.ZError: names the unknown or wrong field
        raise _issue(path, "a valid Zenoh config (JSON5)", str(exc).split(" at /")[0]) from None


def get(cfg: ZenohConfig, key: str) -> Any:
    return json.loads(cfg.get_json(key))


def secure(cfg: _Config) -> _Config:
    """Multicast and gossip scouting off unless the config set them itself."""
    for key in SCOUTING_KEYS:
        if get(cfg, key) is None:
            cfg.insert_json5(key, "false")
    return cfg


def endpoints(cfg: ZenohConfig, which: str) -> list[str]:
    eps = get(cfg, f"{which}/endpoints")
    if isinstance(eps, dict):  # per-mode endpoints: {router: [...], peer: [...], ...}
        eps = eps.get(get(cfg, "mode") or "peer") or []
    return [str(e) for e in eps or []]


def daemon_config(file: str | None, listen: str = DEFAULT_LISTEN) -> Any:
    """The daemon's session: the file as given, or a peer listening on `listen` that
    takes at most MAX_SESSIONS client sessions at once, messages of at most
    MAX_MESSAGE_BYTES, and no shared-memory transport."""
    zenoh = _zenoh()
    if file is not None:
        cfg = load_file(file)
    else:
        cfg = zenoh.Config.from_json5(json.dumps(
            {"mode": "peer", "listen": {"endpoints": [listen]},
             "connect": {"endpoints": []},
             "transport": {"unicast": {"max_sessions": MAX_SESSIONS},
                           "link": {"rx": {"max_message_size": MAX_MESSAGE_BYTES}},
                           "shared_memory": {"enabled": False}}}))
    return secure(cfg)


def _connect_for(listen: str) -> str:
    """A listen endpoint as a client reaches it on the same host."""
    proto, _, addr = listen.partition("/")
    addr = addr.split("#", 1)[0]
    host, _, port = addr.rpartition(":")
    if host in ("0.0.0.0", ""):
        host = "127.0.0.1"
    elif host in ("[::]", "::"):
        host = "[::1]"
    return f"{proto}/{host}:{port}"


def client_config(file: str | None = None, connect: str | None = None) -> Any:
    """A CLI client's session: client mode, connecting to `connect`, to the file's
    connect endpoints, or (a daemon's file, with listen endpoints only) to where that
    daemon listens; with neither, to the default `tcp/127.0.0.1:7447`."""
    zenoh = _zenoh()
    if file is None:
        cfg = zenoh.Config.from_json5(json.dumps(
            {"mode": "client", "connect": {"endpoints": [connect or DEFAULT_LISTEN]}}))
        return secure(cfg)
    cfg = load_file(file)
    if connect is not None:
        eps = [connect]
    else:
        eps = endpoints(cfg, "connect") or [_connect_for(e) for e in endpoints(cfg, "listen")]
    if not eps:
        raise _issue(file, "connect or listen endpoints to reach the daemon or router",
                     "neither")
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps(eps))
    cfg.insert_json5("listen/endpoints", "[]")
    return secure(cfg)


def router_config(file: str) -> Any:
    """`pamd router`: the file, in router mode, with endpoints to listen on."""
    cfg = load_file(file)
    mode = get(cfg, "mode")
    if mode not in (None, "router"):
        raise _issue(file, "mode: \"router\" (or no mode)", f"mode {mode!r}")
    cfg.insert_json5("mode", '"router"')
    if not endpoints(cfg, "listen"):
        raise _issue(file, "listen endpoints (e.g. tls/0.0.0.0:7447)", "none")
    return secure(cfg)


def open_error(exc: BaseException, cfg: ZenohConfig) -> str:
    """What an operator needs to read when a session does not open."""
    text = str(exc).split(" at /")[0]
    if "Address already in use" in text or "address in use" in text.lower():
        eps = ", ".join(endpoints(cfg, "listen")) or "its endpoint"
        return (f"cannot listen on {eps}: the address is in use (another pamd or Zenoh "
                "router?); set telemetry.listen or telemetry.zenoh_config, or run with "
                "--no-telemetry")
    if "Unable to connect" in text:
        eps = ", ".join(endpoints(cfg, "connect")) or "its endpoints"
        why = _tls_why(cfg)
        if why:
            return f"cannot connect to {eps}: {why}"
        return f"cannot connect to {eps} (nothing listening, or refused: TLS/credentials?)"

    return listen_error(text, get(cfg, "transport/link/tls/listen_certificate")) or text


def _tls_why(cfg: ZenohConfig) -> str | None:
    """Which side refused a `tls/` connection and why (`pamd.net.tlsprobe`)."""

    tls = [e for e in endpoints(cfg, "connect") if e.startswith("tls/")]
    if not tls:
        return None
    path = "transport/link/tls/"
    return "; ".join(diagnose(e, get(cfg, path + "root_ca_certificate"),
                              get(cfg, path + "connect_certificate"),
                              get(cfg, path + "connect_private_key")) for e in tls)

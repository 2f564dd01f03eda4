"""The io process's telemetry and live-view specs from the config and the caller's
request, decided in the daemon before anything starts (`resolve_all`), links in clear
beyond loopback included (`pamd.wire.cleartext`)."""

from __future__ import annotations

import json
import os
import secrets
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.config.names import check_chunk
from pamd.iohost.viewer_spec import ViewerSpec
from pamd.iohost.viewer_spec import resolve as resolve_viewer
from pamd.loop.stalls import stall_limit
from pamd.wire import cleartext, zconf
from pamd.wire.cleartext import is_loopback_host
from pamd.wire.credential import ensure_token
from pamd.wire.errors import ConfigError, ConfigIssue
from pamd.wire.local_channel import socket_path as local_socket_path
from pamd.wire.net_spec import NetSpec, TelemetryRequest


@dataclass(frozen=True)
class Resolved:
    """What the io process of a run serves: the Zenoh session's spec (None: telemetry
    off), the Foxglove live view's (None: none) and the warnings the start says (the
    links in clear allowed on purpose; the status says them too, in NetSpec.warnings)."""

    net: NetSpec | None
    viewer: ViewerSpec | None
    warnings: tuple[str, ...]


def resolve(cfg: LoadedConfig, req: TelemetryRequest | None) -> NetSpec | None:
    """The io process's telemetry spec, or None (`resolve_all`)."""
    return resolve_all(cfg, req).net


def resolve_all(cfg: LoadedConfig, req: TelemetryRequest | None) -> Resolved:
    """The run's telemetry and live view, decided before anything starts. Every link
    they open in clear beyond loopback (the Zenoh session's listen and connect
    endpoints, the live view's plain WebSocket) is judged by one rule
    (pamd.wire.cleartext): refused unless allowed (a ConfigError), allowed and warned."""
    viewer = resolve_viewer(cfg, req.foxglove if req is not None else None)
    session = _session(cfg, req)
    exposed = [] if session is None else _zenoh_exposures(cfg, *session)
    if viewer is not None and not viewer.tls and not is_loopback_host(viewer.host):
        exposed.append(_viewer_exposure(cfg, req, viewer))
    allowed = cfg.rig.telemetry.allow_cleartext or (req is not None and req.allow_cleartext)
    warnings = cleartext.judge(exposed, allowed, cleartext.DAEMON_FLAG)
    net = None if session is None else _net_spec(cfg, session[0], warnings)
    return Resolved(net, viewer, warnings)


def _session(cfg: LoadedConfig, req: TelemetryRequest | None
             ) -> tuple[zconf.ZenohConfig, str | None, bool] | None:
    """The daemon's Zenoh config, where it came from (a Zenoh config file, or None:
    the rig config's telemetry section) and whether --listen set its listen endpoint;
    None when telemetry is off (by the request, by `telemetry.enabled`, or, when that
    is null, by the virtual clock). A bad Zenoh config file or a rig id that cannot be
    a key is refused here (ConfigError)."""
    tc = cfg.rig.telemetry
    on = tc.enabled if tc.enabled is not None else cfg.rig.loop.clock == "real"
    if req is not None and req.enabled and req.listen:
        on = True
    if req is None or not req.enabled or not on:
        return None
    problems = [p for p in [check_chunk("rig_id", cfg.rig.rig_id)] + [
        check_chunk("muscle name", m.name) for m in cfg.rig.muscles] if p]
    if problems:
        raise ConfigError([ConfigIssue(cfg.path, None, "rig_id", p) for p in problems])
    file = req.zenoh_config
    if file is None and tc.zenoh_config is not None:
        file = os.path.join(os.path.dirname(os.path.abspath(cfg.path)),
                            os.path.expanduser(tc.zenoh_config))
    zcfg = zconf.daemon_config(file, req.listen or tc.listen, tc.max_sessions)
    if file is not None and req.listen:
        zcfg.insert_json5("listen/endpoints", json.dumps([req.listen]))
    return zcfg, file, bool(req.listen)


def _net_spec(cfg: LoadedConfig, zcfg: zconf.ZenohConfig, warnings: tuple[str, ...]
              ) -> NetSpec:
    """The io process's telemetry spec. The command token (`pamd.wire.credential`) is
    kept or made here: commands need it, loopback included."""
    tc = cfg.rig.telemetry
    rate = cfg.rig.loop.rate_hz
    listen, connect = zconf.endpoints(zcfg, "listen"), zconf.endpoints(zcfg, "connect")
    where = "; ".join(w for w in (listen and "listening on " + ", ".join(listen),
                                  connect and "connecting to " + ", ".join(connect)) if w)
    token_file, token_sha256 = ensure_token(cfg.rig.rig_id)
    return NetSpec(
        token_file=token_file, token_sha256=token_sha256, rig_id=cfg.rig.rig_id,
        run_nonce=secrets.token_hex(8), listen=tuple(listen), warnings=warnings,
        local_socket=local_socket_path(token_file, cfg.rig.rig_id, os.getpid()),
        stall_fault_s=stall_limit(cfg.rig).fault_s,
        muscles=tuple(m.name for m in cfg.rig.muscles),
        zenoh_json=str(zcfg), where=where or "no endpoints",
        every_ticks=max(1, round(rate / tc.rate_hz)),
        publish_period_s=1.0 / tc.publish_hz,
        command_rate_per_s=tc.command_rate_per_s, command_burst=tc.command_burst,
        command_timeout_s=tc.command_timeout_s, status_period_s=1.0 / tc.status_hz)


def _line_of(text: str, dotted: str) -> int | None:
    """The line of a nested key (`telemetry.foxglove.listen`) in a YAML text, by its
    indentation; a flow mapping (`foxglove: {listen: ...}`) gives its line. None if the
    key is not there (its default)."""
    want = dotted.split(".")
    stack: list[int] = []  # the indents of the keys matched so far
    for i, line in enumerate(text.splitlines(), 1):
        stripped = line.lstrip()
        if not stripped or stripped.startswith("#"):
            continue
        col = len(line) - len(stripped)
        while stack and col <= stack[-1]:
            stack.pop()
        if stripped.split(":", 1)[0].strip() == want[len(stack)]:
            stack.append(col)
            rest = want[len(stack):]
            if not rest or all(f"{k}:" in stripped for k in rest):
                return i
    return None


#: what the daemon's links carry, and how to encrypt each instead
ZENOH_CARRIES = "state, status and signed commands"
ZENOH_TLS = "tls/...: config/zenoh/lab-daemon.json5 reaches a router with mutual TLS"
VIEW_CARRIES = "the live state, loop timing and events"
VIEW_TLS = "wss://: telemetry.foxglove.tls_cert and tls_key"


def _zenoh_exposures(cfg: LoadedConfig, zcfg: zconf.ZenohConfig, file: str | None,
                     by_flag: bool) -> list[cleartext.Exposure]:
    """The daemon's Zenoh endpoints in clear beyond loopback, each named where it was
    set (--listen, the Zenoh config file's line, the rig config's telemetry.listen)."""
    out = []
    for which, role in (("listen", "the Zenoh session listens on"),
                        ("connect", "the Zenoh session connects to")):
        for e in zconf.cleartext_beyond_loopback(zcfg, which):
            if which == "listen" and by_flag:
                where, line, key = "--listen", None, ""
            elif file is not None:
                where, line, key = file, zconf.endpoint_line(file, e), f"{which}/endpoints"
            else:
                where, key = cfg.path, "telemetry.listen"
                line = _line_of(cfg.text, key)
            out.append(cleartext.Exposure(role, e, ZENOH_CARRIES, ZENOH_TLS, where, line, key))
    return out


def _viewer_exposure(cfg: LoadedConfig, req: TelemetryRequest | None, viewer: ViewerSpec
                     ) -> cleartext.Exposure:
    """The Foxglove live view's plain WebSocket beyond loopback, named where it was set."""
    by_flag = req is not None and req.foxglove not in (None, "default")
    key = "telemetry.foxglove.listen"
    where, line = ("--foxglove", None) if by_flag else (cfg.path, _line_of(cfg.text, key))
    return cleartext.Exposure("the Foxglove live view serves on", viewer.url, VIEW_CARRIES,
                              VIEW_TLS, where, line, "" if by_flag else key)

"""The io process's telemetry spec from the config and the caller's request, decided
in the daemon before anything starts (`resolve`)."""

from __future__ import annotations

import json
import os
import secrets

from pamd.config.loader import LoadedConfig
from pamd.config.names import check_chunk
from pamd.errors import ConfigError, ConfigIssue
from pamd.net import zconf
from pamd.net.credential import ensure_token
from pamd.net.local import socket_path as local_socket_path
from pamd.net.spec import NetSpec, TelemetryRequest
from pamd.stalls import stall_limit


def resolve(cfg: LoadedConfig, req: TelemetryRequest | None) -> NetSpec | None:
    """The io process's telemetry spec, or None when telemetry is off (by the request,
    by `telemetry.enabled`, or, when that is null, by the virtual clock). A bad Zenoh
    config file or a rig id that cannot be a key is refused here, before anything
    starts (ConfigError). The command token (`pamd.net.credential`) is kept or made
    here: commands need it, loopback included."""
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
    rate = cfg.rig.loop.rate_hz
    zcfg = zconf.daemon_config(file, req.listen or tc.listen, tc.max_sessions)
    if file is not None and req.listen:
        zcfg.insert_json5("listen/endpoints", json.dumps([req.listen]))
    listen, connect = zconf.endpoints(zcfg, "listen"), zconf.endpoints(zcfg, "connect")
    where = "; ".join(w for w in (listen and "listening on " + ", ".join(listen),
                                  connect and "connecting to " + ", ".join(connect)) if w)
    source = "--listen" if req.listen else file
    warnings = _cleartext(cfg, zcfg, source, req.allow_cleartext)
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


def _line_of(text: str, section: str, key: str) -> int | None:
    """The line of `key:` inside the top-level `section:` of a YAML text (None if not
    there: the default)."""
    inside = False
    for i, line in enumerate(text.splitlines(), 1):
        if line and not line[0].isspace():
            inside = line.split(":", 1)[0].strip() == section
        elif inside and line.strip().startswith(f"{key}:"):
            return i
    return None


def _cleartext(cfg: LoadedConfig, zcfg: zconf.ZenohConfig, source: str | None,
               allowed: bool) -> tuple[str, ...]:
    """Listening beyond loopback without TLS: refused (ConfigError) unless allowed
    (`--allow-cleartext`, `telemetry.allow_cleartext`); allowed, the warning the start
    and every status say. `source`: where the endpoint came from (--listen, a Zenoh
    config file; None: the rig config's telemetry.listen)."""
    clear = zconf.cleartext_beyond_loopback(zcfg)
    if not clear:
        return ()
    eps = ", ".join(clear)
    if not (allowed or cfg.rig.telemetry.allow_cleartext):
        line = None if source else _line_of(cfg.text, "telemetry", "listen")
        key = "listen/endpoints" if source else "telemetry.listen"
        raise ConfigError([ConfigIssue(
            source or cfg.path, line, key, "loopback (tcp/127.0.0.1:...) or TLS (tls/...: "
            "config/zenoh/lab-daemon.json5 reaches a router with mutual TLS)",
            f"{eps}: beyond loopback without TLS (state, status and commands in clear on "
            "the network); to run so anyway, say it: pamd run --allow-cleartext, or "
            "telemetry.allow_cleartext: true")])
    return (f"telemetry listens on {eps} beyond loopback WITHOUT TLS (allowed by "
            "--allow-cleartext / telemetry.allow_cleartext): anyone on that network can "
            "read state and status and reach the daemon (commands stay signed)",)

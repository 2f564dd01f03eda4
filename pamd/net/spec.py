"""What the daemon asks of telemetry (`TelemetryRequest`, from the CLI) and what it
tells the io process (`NetSpec`, picklable, handed over at spawn)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.config.names import check_chunk
from pamd.errors import ConfigError, ConfigIssue
from pamd.net import zconf
from pamd.net.credential import ensure_token


@dataclass(frozen=True)
class TelemetryRequest:
    """The caller's say: `pamd run` asks for telemetry as the config says unless
    `--no-telemetry`; `--zenoh-config` overrides `telemetry.zenoh_config`."""

    enabled: bool = True
    zenoh_config: str | None = None
    # The live Foxglove view (pamd.view.spec.resolve): None as telemetry.foxglove says,
    # "default" on at its listen address, "HOST:PORT" on there. Independent of `enabled`.
    foxglove: str | None = None
    # `pamd run --listen ENDPOINT`: where the daemon's session listens (overrides
    # telemetry.listen, and the listen endpoints of a Zenoh config file); asking for it
    # turns telemetry on, a virtual-clock run's too
    listen: str | None = None


@dataclass(frozen=True)
class NetSpec:
    rig_id: str
    muscles: tuple[str, ...]
    zenoh_json: str  # the session's whole config (zenoh.Config as JSON)
    every_ticks: int  # one state sample per this many ticks
    publish_period_s: float  # at most one put per muscle per this
    command_rate_per_s: float
    command_burst: int
    command_timeout_s: float
    status_period_s: float = 0.1  # the main thread's status snapshot refresh
    where: str = ""  # where the session listens or connects, for the operator
    board_name: str = ""  # the shared status board (pamd.net.board), set at creation
    token_sha256: str = ""  # the command credential's hash ("": commands need none)
    token_file: str = ""  # where the token is, for a refusal to say


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
    zcfg = zconf.daemon_config(file, req.listen or tc.listen)
    if file is not None and req.listen:
        zcfg.insert_json5("listen/endpoints", json.dumps([req.listen]))
    listen, connect = zconf.endpoints(zcfg, "listen"), zconf.endpoints(zcfg, "connect")
    where = "; ".join(w for w in (listen and "listening on " + ", ".join(listen),
                                  connect and "connecting to " + ", ".join(connect)) if w)
    token_file, token_sha256 = ensure_token(cfg.rig.rig_id)
    return NetSpec(
        token_file=token_file, token_sha256=token_sha256, rig_id=cfg.rig.rig_id,
        muscles=tuple(m.name for m in cfg.rig.muscles),
        zenoh_json=str(zcfg), where=where or "no endpoints",
        every_ticks=max(1, round(rate / tc.rate_hz)),
        publish_period_s=1.0 / tc.publish_hz,
        command_rate_per_s=tc.command_rate_per_s, command_burst=tc.command_burst,
        command_timeout_s=tc.command_timeout_s, status_period_s=1.0 / tc.status_hz)

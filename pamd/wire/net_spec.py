"""What the daemon asks of telemetry (`TelemetryRequest`, from the CLI) and what it
tells the io process (`NetSpec`, picklable, handed over at spawn). The config decides
them in the daemon (`pamd.daemon.host.resolve`), so the io process needs no config."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TelemetryRequest:
    """The caller's say: `pamd run` asks for telemetry as the config says unless
    `--no-telemetry`; `--zenoh-config` overrides `telemetry.zenoh_config`."""

    enabled: bool = True
    zenoh_config: str | None = None
    # The live Foxglove view (pamd.iohost.viewer_spec.resolve): None as telemetry.foxglove says,
    # "default" on at its listen address, "HOST:PORT" on there. Independent of `enabled`.
    foxglove: str | None = None
    # `pamd run --listen ENDPOINT`: where the daemon's session listens (overrides
    # telemetry.listen, and the listen endpoints of a Zenoh config file); asking for it
    # turns telemetry on, a virtual-clock run's too
    listen: str | None = None
    # `pamd run --allow-cleartext`: listening beyond loopback without TLS (plain tcp on
    # 0.0.0.0) is refused unless this or telemetry.allow_cleartext says so; warned then
    allow_cleartext: bool = False


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
    board_name: str = ""  # the shared status board (pamd.wire.board), set at creation
    token_sha256: str = ""  # the command credential's hash ("": commands need none)
    token_file: str = ""  # where the token is, for a refusal to say
    run_nonce: str = ""  # this run's, in every command's MAC (pamd.wire.credential)
    local_socket: str = ""  # the local channel's path (pamd.wire.local_channel; "": none)
    listen: tuple[str, ...] = ()  # the session's listen endpoints (the local channel says them)
    warnings: tuple[str, ...] = ()  # said at start and in every status (cleartext beyond
    # loopback, allowed by --allow-cleartext)
    # the loop's stall fault limit (pamd.loop.stalls): a loop that writes no tick record this
    # long is not running (it would latch FAULT), so its status is stale
    stall_fault_s: float = 0.5

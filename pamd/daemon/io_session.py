"""An io process attached to a daemon: builds the shared block and the spec, puts
the ring sink downstream of the summary sink and the ring mailbox beside the local
one, and decides what a lost io process or a failed write means (by config: fault to
the safe state, or keep controlling without recording; either way it says so).

It starts when the run records, publishes telemetry (`pamd.iohost`), or both; with
telemetry it also owns the status board and the main thread's share of it
(`service`, `stopping`)."""

from __future__ import annotations

import dataclasses
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.daemon.host.host import NetHost
from pamd.daemon.host.parts import HostParts
from pamd.daemon.host.resolve import resolve_all
from pamd.daemon.record_meta import build_record_spec
from pamd.iohost.io_spec import IoSpec
from pamd.iohost.viewer_spec import ViewerSpec
from pamd.loop.control.controller import RigController
from pamd.loop.control.summary import LocalMailbox, SummarySink
from pamd.loop.devices.datum_file import Calibration
from pamd.loop.io_link import IoLink, MultiMailbox, RingMailbox, RingSink
from pamd.loop.loop import Loop
from pamd.wire.board import Board
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.net_spec import NetSpec, TelemetryRequest
from pamd.wire.ring import BlockLayout, pow2_at_least
from pamd.wire.tick import TickLayout


@dataclass(frozen=True)
class IoParts:
    """What the daemon (`pamd.daemon.daemon.Daemon`) hands its io session, never itself: the
    config in force (`config()`: a reload replaces it), the run's note, the tick's
    layout and the datums (the recording's metadata), the rig's controller (its
    clock, counters and supervisor: a lost io process may fault it), the loop (its
    clock, real, virtual or daq, its notices, and the mailbox the ring's commands
    join), the summary sink (the ring sink goes downstream of it) and the loop's local
    mailbox."""

    config: Callable[[], LoadedConfig]
    note: str
    layout: TickLayout
    calibration: Calibration
    ctrl: RigController
    loop: Loop
    summary: SummarySink
    mailbox: LocalMailbox


def io_nice(cfg: LoadedConfig) -> int | None:
    """The io process's nice value: `loop.realtime.io_nice` when real-time settings are
    on and the clock is real (a virtual-clock run waits for its io process anyway)."""
    rt = cfg.rig.loop.realtime
    return rt.io_nice if rt.enabled and cfg.rig.loop.clock == "real" else None


@dataclass(frozen=True)
class RecordingRequest:
    """What the caller (CLI, tests) asks of the io process for one run."""

    dir: str | None = None  # overrides recording.dir of the config
    enabled: bool = True  # False: no recording even if the config names a dir
    run_name: str | None = None
    model_path: str | None = None  # the ANFIS model in use, attached to the file
    profile: JsonObject | None = None  # the profile or experiment step, as metadata
    script: tuple[tuple[int, str, JsonObject], ...] = ()  # io-side (tick, verb, payload)
    fsize_limit_bytes: int | None = None  # tests: make writes fail for real
    segments: tuple[JsonObject, ...] = ()  # experiment steps: one file each
    max_mb: float | None = None  # the run's files stop taking ticks past this size


class IoSession:
    def __init__(self, parts: IoParts, req: RecordingRequest, record_dir: str | None,
                 net: NetSpec | None = None, viewer: ViewerSpec | None = None,
                 warnings: tuple[str, ...] = ()) -> None:
        self.parts = parts
        self.warnings = warnings  # links in clear allowed on purpose: said at start
        cfg = parts.config()
        self.rc = cfg.rig.recording
        loop = parts.loop
        self.virtual = loop.virtual
        self.failure: JsonObject | None = None
        self.recording = record_dir is not None  # False: telemetry alone
        self.max_mb = req.max_mb
        clock0 = 0.0 if self.virtual else time.monotonic()
        wall0 = time.time_ns()
        rate = cfg.rig.loop.rate_hz
        layout = BlockLayout(record_bytes=8 * parts.layout.size,
                             tick_slots=pow2_at_least(max(64, int(self.rc.ring_s * rate))))
        rspec = None if record_dir is None else build_record_spec(
            cfg, parts.calibration, record_dir=record_dir, note=parts.note,
            run_name=req.run_name, model_path=req.model_path, profile=req.profile,
            virtual=self.virtual, wall0_ns=wall0, fsize_limit_bytes=req.fsize_limit_bytes,
            steps=req.segments, max_mb=req.max_mb)
        # Telemetry: the status board the main thread writes (pamd.wire.board)
        self.board: Board | None = None
        self.host: NetHost | None = None
        if net is not None:
            self.board = Board(create=True)
            net = dataclasses.replace(net, board_name=self.board.name)
            host_parts = HostParts(parts.ctrl, parts.loop, parts.config, parts.note,
                                   parts.summary, parts.mailbox, self)
            self.host = NetHost(host_parts, self.board, cfg.rig.telemetry.status_hz, record_dir)
        self.net = net
        self.viewer = viewer

        def make_spec(shm_name: str) -> IoSpec:
            return IoSpec(shm_name=shm_name, layout=layout, rig_id=cfg.rig.rig_id,
                          muscles=tuple(parts.layout.muscles), rate_hz=rate,
                          virtual=self.virtual, wall0_ns=wall0, clock0_s=clock0,
                          parent_pid=os.getpid(), record=rspec, script=tuple(req.script),
                          net=net, viewer=viewer, nice=io_nice(cfg))

        self.link = IoLink.create(make_spec, layout)
        ctrl = parts.ctrl
        self.sink = RingSink(self.link, self.virtual, lambda: ctrl.t_start, self._failed,
                             loop.notices.append, keeps_draining=net is not None)
        self.mailbox = RingMailbox(self.link, self.sink, lambda: ctrl.now)
        parts.summary.downstream.append(self.sink)
        loop.mailbox = MultiMailbox(parts.mailbox, self.mailbox)

    def files(self) -> list[str]:
        """The recording's files so far (the status says them)."""
        return self.link.files()

    @property
    def lost_records(self) -> int:
        """Tick records lost to a full io ring so far (the loop's count)."""
        return self.sink.lost_records

    @classmethod
    def attach(cls, parts: IoParts, req: RecordingRequest | None,
               telemetry: TelemetryRequest | None = None) -> IoSession | None:
        """An io process when the run records, publishes (telemetry), or both."""
        req = req or RecordingRequest()
        cfg = parts.config()
        record_dir = req.dir or cfg.rig.recording.dir
        if not req.enabled or not record_dir:
            record_dir = None
        got = resolve_all(cfg, telemetry)  # ConfigError before anything starts
        if record_dir is None and got.net is None and got.viewer is None:
            return None
        return cls(parts, req, record_dir, got.net, got.viewer, got.warnings)

    def start(self) -> None:
        try:
            self.link.start()
        except BaseException:
            if self.board is not None:
                self.board.close()
                self.board = None
            raise
        log = logging.getLogger("pamd")
        if self.net is not None:
            log.info("telemetry: pamd/%s/** (%s)", self.net.rig_id, self.net.where)
        if self.viewer is not None:
            log.info("foxglove: live view on %s (Foxglove: Open connection, Foxglove "
                     "WebSocket)", self.viewer.url)
        for w in self.warnings:
            log.warning("%s", w)

    def discard(self) -> None:
        """The run was refused before it started (a lock held, a device missing): stop
        the io process if it runs, free the shared block and the status board, so
        nothing is left behind (no leaked shared memory, no warning at exit)."""
        if not self.link.closed:
            self.link.close()
        if self.board is not None:
            self.board.close()
            self.board = None

    def service(self) -> None:
        """The main thread's share (Daemon.service): status snapshot, main-thread
        commands (collect, model)."""
        if self.host is not None and self.board is not None:
            self.host.service()

    def stopping(self, reason: str) -> None:
        """A stop was requested: the io process withdraws the liveliness token and
        refuses new commands at once."""
        if self.host is not None and self.board is not None:
            self.host.stopping(reason)

    def _failed(self, what: str, reason: str) -> None:
        """In the loop's thread: the io process died or could not write."""
        policy = self.rc.on_io_death if what == "death" else self.rc.on_failure
        key = "on_io_death" if what == "death" else "on_failure"
        ctrl = self.parts.ctrl
        gone = "recording" if what == "write" else " and ".join(
            w for w, on in (("recording", self.recording),
                            ("telemetry", self.net is not None),
                            ("the Foxglove view", self.viewer is not None))
            if on)
        if policy == "safe_state":
            msg = f"{gone} stopped: {reason}; going to the safe state (recording.{key})"
        else:
            msg = (f"{gone} stopped: {reason}; control continues WITHOUT {gone} "
                   f"(recording.{key}: continue)")
        self.failure = {"what": what, "reason": reason, "policy": policy,
                        "tick": ctrl.tick_no}
        self.parts.loop.notices.append(msg)
        self.parts.summary.event(ctrl.now, "recording", dict(self.failure, message=msg))
        if policy == "safe_state":
            ctrl.supervisor.fault(ctrl.now, f"recording: {reason}")

    def close(self, summary: JsonObject) -> None:
        if self.link.closed:
            return
        self.sink.finish(summary)
        self.link.close()
        if self.host is not None:  # a remote collection still open: its manifest
            try:
                self.host.close(str(summary.get("stop_reason") or "stopped"))
            except Exception:  # never in the way of the rest of the shutdown
                logging.getLogger("pamd").exception("closing the remote collection")
        if self.board is not None:
            self.board.close()
            self.board = None

    def result(self) -> JsonObject:
        st = self.link.status()
        st["lost_records"] = self.sink.lost_records
        st["lost_events"] = max(self.sink.lost_events, st.get("lost_events") or 0)
        st["failure"] = self.failure
        st["max_mb"] = self.max_mb
        return st

    def telemetry(self) -> JsonObject | None:
        """What the run's summary says of telemetry (None when it was off)."""
        if self.net is None:
            return None
        return {"rig_id": self.net.rig_id, "every_ticks": self.net.every_ticks,
                "failure": self.failure if not self.recording else None}

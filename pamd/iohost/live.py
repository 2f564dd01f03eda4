"""The live view: a Foxglove WebSocket server in the io process (never the loop's).

It carries the recording's own channels and schemas, so one Foxglove layout
(config/foxglove/pamd-layout.json) shows a live rig and a recorded file alike:

  /pamd/<rig>/state/<muscle>  pamd_msgs/msg/MuscleState  ros2msg, cdr
  /pamd/<rig>/loop            pamd_msgs/msg/LoopTiming   ros2msg, cdr
  /pamd/<rig>/events          pamd_msgs/msg/Event        jsonschema, json

State and loop messages are decimated like the Zenoh state: one tick in
`loop.rate_hz / telemetry.rate_hz`, with the recording's log time (the tick's
scheduled wall-clock time). Events are all sent.

Never in the loop's way: the io process hands each message to the foxglove-sdk
(a Rust server on its own threads, which take no Python lock) and goes on; each
viewer has a bounded queue (`BACKLOG`) whose oldest data is dropped when the viewer
does not keep up (the server disconnects a viewer whose control messages back up).
The server takes no commands (no client publishing, no services): commands stay on
Zenoh, where the router authenticates them.

What the server says of its clients (a garbage frame, a subscribe to an unknown
channel, a dropped connection) comes through Python's logging (logger `foxglove`) and
goes to stderr one line per pattern per 10 s, each saying how many like it were dropped
(`pamd.iohost.ratelimit`): a client cannot grow the daemon's log (one line per bad frame
was 108 MB in 100 s).
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from pamd.iohost.ratelimit import RateLimitedHandler, limit_logger
from pamd.iohost.recorder import record_schemas
from pamd.iohost.viewer_spec import ViewerSpec
from pamd.wire.declare.jsonsafe import JsonObject, dumps
from pamd.wire.record import cdr
from pamd.wire.seams import RunClock
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS

if TYPE_CHECKING:  # foxglove-sdk: an optional extra, imported on `open`; its types only
    from foxglove import Channel, Context
    from foxglove.websocket import WebSocketServer

BACKLOG = 1024  # messages queued per viewer before its oldest are dropped
LOG_FLUSH_S = 1.0
FOXGLOVE_LOGGER = "foxglove"  # the SDK's (Rust) log records come out under this


class LiveView:
    """The io process's Foxglove server: `open`, then `ticks` and `event` from the io
    loop's one thread, `close` at the end."""

    def __init__(self, spec: ViewerSpec, io_spec: RunClock, t_start: Callable[[], float | None]
                 ) -> None:
        self.spec = spec
        self.io_spec = io_spec
        self.t_start = t_start  # the loop's start on its clock, once known
        self.period_ns = round(1e9 / io_spec.rate_hz)
        self.every = spec.every_ticks
        mf, lf = cdr.muscle_fields(), cdr.loop_fields()
        self.mus_payload = cdr.compile_payload(mf)
        self.loop_payload = cdr.compile_payload(lf)
        self.mus_int = [i for i, (_n, t) in enumerate(mf) if t != "float64"]
        self.loop_int = [i for i, (_n, t) in enumerate(lf) if t != "float64"]
        self.n_loop, self.n_mf = len(LOOP_FIELDS), len(MUSCLE_FIELDS)
        self.server: WebSocketServer | None = None
        self.ctx: Context | None = None
        self.state_ch: list[Channel] = []
        self.loop_ch: Channel | None = None  # the channels are set with the server
        self.events_ch: Channel | None = None
        self.sent = 0
        self.log: RateLimitedHandler | None = None  # what the server says, rate limited
        self.log_t = 0.0

    def open(self) -> str | None:
        """Start the server and declare the channels; an error text if it cannot."""
        try:
            import foxglove
        except ImportError:
            return ("the foxglove-sdk package is not installed (pip install "
                    "'foxglove-sdk>=0.30.3,<0.31')")
        sp = self.spec
        self.log = limit_logger(FOXGLOVE_LOGGER, "pamd: foxglove: ")
        # ours alone (nothing else logs into it); kept: a dropped context closes its channels
        ctx = self.ctx = foxglove.Context()
        try:
            self.server = foxglove.start_server(
                name=f"pamd {sp.rig_id}", host=sp.host, port=sp.port, context=ctx,
                message_backlog_size=BACKLOG, tls_cert=sp.tls_cert, tls_key=sp.tls_key)
        except Exception as exc:  # FoxgloveError: address in use, cannot bind
            text = str(exc).removeprefix("FoxgloveError: ")
            hint = (" (another pamd or Foxglove bridge is serving there? choose another "
                    "with --foxglove HOST:PORT or telemetry.foxglove.listen)"
                    if "in use" in text else "")
            return f"cannot serve on {sp.host}:{sp.port}: {text}{hint}"
        (mname, menc, mdata), (lname, lenc, ldata), (ename, eenc, edata) = record_schemas()
        root = f"/pamd/{sp.rig_id}"
        self.state_ch = [foxglove.Channel(
            f"{root}/state/{m}", message_encoding="cdr", context=ctx, metadata={"muscle": m},
            schema=foxglove.Schema(name=mname, encoding=menc, data=mdata))
            for m in sp.muscles]
        self.loop_ch = foxglove.Channel(
            f"{root}/loop", message_encoding="cdr", context=ctx,
            schema=foxglove.Schema(name=lname, encoding=lenc, data=ldata))
        self.events_ch = foxglove.Channel(
            f"{root}/events", message_encoding="json", context=ctx,
            schema=foxglove.Schema(name=ename, encoding=eenc, data=edata))
        return None

    def _log_ns(self, tick: int, t_s: float) -> int:
        """The recording's log time of a tick (pamd.iohost.recorder.Recorder.tick)."""
        io = self.io_spec
        if io.virtual:
            return io.wall0_ns + tick * self.period_ns
        return io.wall0_ns + round(((self.t_start() or 0.0) + t_s - io.clock0_s) * 1e9)

    def ticks(self, rows: Sequence[Sequence[float]]) -> None:
        """Tick records drained from the ring: one in `every_ticks` goes out. A failure
        ends the view alone (said once); recording and telemetry go on."""
        if self.server is None:
            return
        now = time.monotonic()
        if self.log is not None and now - self.log_t >= LOG_FLUSH_S:
            self.log_t = now
            self.log.flush_due(now)  # the counts of a flood that ended
        try:
            self._ticks(rows)
        except Exception as exc:
            self._give_up(exc)

    def _ticks(self, rows: Sequence[Sequence[float]]) -> None:
        every, nl, nm = self.every, self.n_loop, self.n_mf
        hdr = cdr.CDR_LE
        loop_ch = self.loop_ch
        assert loop_ch is not None  # opened with the server (`ticks` checked it)
        for row in rows:
            tick = int(row[0])
            if tick % every:
                continue
            log_ns = self._log_ns(tick, row[1])
            vals = list(row[:nl])
            for i in self.loop_int:
                vals[i] = int(vals[i])
            loop_ch.log(self.loop_payload.pack(hdr, *vals), log_time=log_ns)
            for k, ch in enumerate(self.state_ch):
                b = nl + k * nm
                mv = [tick, row[1], *row[b:b + nm]]
                for i in self.mus_int:
                    mv[i] = int(mv[i])
                ch.log(self.mus_payload.pack(hdr, *mv), log_time=log_ns)
            self.sent += 1

    def event(self, t_abs_s: float, name: str, data: JsonObject) -> None:
        """An event as the recording writes it (`t_s`, `tick`, `kind`, `data`)."""
        if self.server is None or name == "summary":
            return
        io = self.io_spec
        t0 = self.t_start()
        t0 = t_abs_s if t0 is None else t0
        log_ns = io.wall0_ns + round((t_abs_s - io.clock0_s) * 1e9)
        try:
            body = dumps({"t_s": t_abs_s - t0, "tick": round((t_abs_s - t0) * io.rate_hz),
                          "kind": name, "data": data})
            assert self.events_ch is not None  # opened with the server (checked above)
            self.events_ch.log(body.encode(), log_time=log_ns)
        except Exception as exc:
            self._give_up(exc)

    def _give_up(self, exc: BaseException) -> None:
        print(f"pamd: foxglove: the live view stopped ({exc.__class__.__name__}: {exc}); "
              "recording and telemetry go on", file=sys.stderr, flush=True)
        with contextlib.suppress(Exception):
            self.close()
        self.server = None

    def close(self) -> None:
        if self.server is None:
            return
        server, self.server = self.server, None
        for ch in (*self.state_ch, self.loop_ch, self.events_ch):
            if ch is not None:
                ch.close()
        server.stop()

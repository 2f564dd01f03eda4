"""The io process: drains the loop's rings into the recorder and the Zenoh node
(`pamd.iohost.node`: telemetry, status, remote commands), bumps the heartbeat the loop
watches, sends commands to the loop and routes their verdicts.

With telemetry, it also takes recording control from the daemon's main thread (the
board's control ring: a collection started over the network, `pamd.wire.record.control`) and
sends the recorder's notices back through the board.

It never blocks the loop: it only reads rings the loop writes without waiting. If a
write fails (disk full, I/O error) it reports the error in the shared header, stops
recording and keeps draining, so the loop decides (safe state or continue) and is
never held up. It ignores SIGINT/SIGTERM (the daemon stops it cleanly through the
stop flag) and finalises its file by itself if the loop's process disappears.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import struct
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

from pamd.iohost.io_spec import IoSpec
from pamd.iohost.node import NetNode
from pamd.iohost.recorder import Recorder
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.ring import (
    C_HEARTBEAT,
    C_IO_STATE,
    C_RECORDED,
    C_STOP,
    IO_DONE,
    IO_FAILED,
    IO_READY,
    SharedBlock,
)
from pamd.wire.verbs.table import VERBS

if TYPE_CHECKING:  # types only; the live view is imported when a run asks for it
    from pamd.iohost.live import LiveView
    from pamd.wire.net_spec import NetSpec
    from pamd.wire.record.record_spec import RecordSpec

IDLE_SLEEP_S = 0.0005
BACKLOG_MAX = 1024  # commands waiting for room in the loop's mailbox
VERDICT_SLEEP_S = 0.0001
BATCH = 512


class RingCommandPort:
    """The io side of the command mailbox: send a command to the loop, get its verdict
    back (through the event ring) by id. The Zenoh session uses the same port, from
    its query callbacks' thread: `lock` makes it the ring's one producer at a time.

    A burst larger than the ring waits here (`backlog`, at most BACKLOG_MAX commands)
    and goes into the ring as the loop takes commands (`flush`, every io pass); an
    `estop` or `stop` goes ahead of the waiting ones."""

    def __init__(self, block: SharedBlock) -> None:
        self.ring = block.commands
        self.next_id = 1
        self.waiting: dict[int, Callable[[JsonObject], None]] = {}
        self.backlog: deque[tuple[int, bytes]] = deque()
        self.lock = threading.RLock()

    def send(self, verb: str, payload: JsonObject | None, sender: str, user: str = "",
             on_verdict: Callable[[JsonObject], None] | None = None) -> int | None:
        """Queue a command; None (and a refusal verdict) if it cannot be queued."""
        with self.lock:
            cid = self.next_id
            self.next_id += 1
            blob = json.dumps({"id": cid, "verb": verb, "payload": payload or {},
                               "sender": sender, "user": user}).encode()
            why = None
            if len(blob) > self.ring.slot_bytes - 4:
                why = f"{verb}: the command is too large ({len(blob)} bytes); not taken"
            elif len(self.backlog) >= BACKLOG_MAX:
                why = (f"the loop's command queue is full ({BACKLOG_MAX} waiting); not "
                       "taken, try again")
            if why is not None:
                if on_verdict:
                    on_verdict({"ok": False, "error": why})
                return None
            if on_verdict is not None:
                self.waiting[cid] = on_verdict
            if VERBS.is_urgent(verb):
                self.backlog.appendleft((cid, blob))
            else:
                self.backlog.append((cid, blob))
            self.flush()
            return cid

    def flush(self) -> int:
        """Into the ring, as far as it has room; the number sent."""
        n = 0
        with self.lock:
            while self.backlog and self.ring.put_blob(self.backlog[0][1]):
                self.backlog.popleft()
                n += 1
        return n

    def on_reply(self, data: JsonObject) -> None:
        with self.lock:
            fn = self.waiting.pop(int(data.get("id", -1)), None)
            if fn is not None:
                fn(data)


def io_main(spec: IoSpec) -> None:
    """Entry point of the spawned io process."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    take_nice(spec.nice)
    block = SharedBlock(spec.layout, spec.shm_name)
    try:
        IoProcess(spec, block).run()
    finally:
        block.close()
        report_modules(os.environ.get(MODULES_ENV))


def take_nice(nice: int | None) -> bool:
    """The io process's priority (`loop.realtime.io_nice`), before it starts a thread:
    every thread it starts (Zenoh's, the Foxglove server's, the local channel's)
    inherits it. Above every normal process, so a loaded PC does not starve the
    recording; below every real-time thread, so the loop and its drivers' threads
    always run first. Refused (no LimitNICE= or CAP_SYS_NICE): said on stderr, and the
    io process runs at normal priority. False then."""
    if nice is None:
        return True
    try:
        os.setpriority(os.PRIO_PROCESS, 0, nice)
    except OSError as exc:
        why = exc.strerror or exc
        print(f"pamd: real-time: the io process could not take nice {nice} ({why}): at "
              "normal priority, a loaded PC can starve its recording (lost tick records, "
              "said as they happen); allow it with LimitNICE= (systemd) or CAP_SYS_NICE",
              file=sys.stderr, flush=True)
        return False
    return True


MODULES_ENV = "PAMD_TEST_IO_MODULES"
"""A test hook (off unless set): the file the io process writes, as it exits, the names
of the modules it imported (tests/io/test_io_imports.py: what it takes is what it needs)."""


def report_modules(path: str | None) -> None:
    if path:
        with open(path, "w") as f:
            json.dump(sorted(sys.modules), f)


class IoProcess:
    def __init__(self, spec: IoSpec, block: SharedBlock) -> None:
        self.spec = spec
        self.block = block
        self.recorder: Recorder | None = None
        self.net: NetNode | None = None  # telemetry and remote commands
        self.viewer: LiveView | None = None  # the Foxglove server
        self.port = RingCommandPort(block)
        self.script = sorted(spec.script)
        self.rec_struct = struct.Struct(f"<{spec.layout.record_bytes // 8}d")
        self.last_tick = -1
        self.failed = False
        self.reply_t = 0.0
        self._next_event: JsonObject | None = None  # read, newer than a step's end

    def _fail(self, what: str, exc: BaseException) -> None:
        reason = f"{what}: {exc.__class__.__name__}: {exc}"
        if isinstance(exc, OSError) and exc.strerror:
            where = exc.filename or (self.recorder.files[-1] if self.recorder is not None
                                     and self.recorder.files else "")
            reason = f"{what}: {exc.strerror}" + (f" ({where})" if where else "")
        self.block.set_error(reason)
        self.block.set(C_IO_STATE, IO_FAILED)
        self.failed = True
        if self.recorder is not None:
            self.recorder.abandon()
            self.recorder = None

    def run(self) -> None:
        if not self._open():
            return
        self.block.set(C_IO_STATE, IO_READY)
        stop_reason, summary = self._serve()
        self._finish(stop_reason, summary)

    def _open(self) -> bool:
        """Open what the spec asks for: the network first (a taken endpoint refuses
        before any file opens), the Foxglove server, the recording. False (reported to
        the daemon, which refuses to start) if one cannot open."""
        spec = self.spec
        if spec.net is not None and not self._open_net(spec.net):
            return False
        if spec.viewer is not None and not self._open_viewer():
            return False
        return spec.record is None or self._open_recording(spec.record)

    def _open_net(self, net: NetSpec) -> bool:
        """Telemetry and remote commands (pamd.iohost)."""
        self.net = NetNode(net, self.spec, self.block, self.port, self._record_event)
        err = self.net.open()
        if err is None:
            return True
        self.net = None  # reported to the daemon, which refuses to start
        self.block.set_error(f"telemetry: {err}")
        self.block.set(C_IO_STATE, IO_FAILED)
        self.failed = True
        return False

    def _open_recording(self, record: RecordSpec) -> bool:
        """The recording, under its file size limit if it has one."""
        if record.fsize_limit_bytes:

            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes fail with EFBIG
            lim = record.fsize_limit_bytes
            resource.setrlimit(resource.RLIMIT_FSIZE, (lim, lim))

        try:
            self.recorder = Recorder(self.spec)
            self.recorder.open()
            self.block.set_files(self.recorder.files)
        except Exception as exc:  # reported to the daemon, which refuses to start
            self._fail("cannot open the recording", exc)
            if self.net is not None:
                self.net.close("the recording could not be opened")
            if self.viewer is not None:
                self.viewer.close()
            return False
        return True

    def _serve(self) -> tuple[str, JsonObject | None]:
        """Drain the loop's ticks and events into their sinks, serve the network and
        the script, until the daemon says stop and all is drained, or the loop's
        process is gone. Returns (why it stopped, the run's summary if it came)."""
        block = self.block
        summary: JsonObject | None = None
        hb = 0
        mono = time.monotonic
        last_parent_check = mono()
        while True:
            hb += 1
            block.set(C_HEARTBEAT, hb)
            stop = block.get(C_STOP)  # read before draining: all data is in by now
            n = self._drain_ticks()
            m, s = self._drain_events()
            if s is not None:
                summary = s
            self._run_script()
            if self.port.backlog:
                self.port.flush()
            now = mono()
            k = self._serve_sinks(now)
            if stop and n == 0 and m == 0:
                return "stopped by the daemon", summary
            if now - last_parent_check > 0.1:
                last_parent_check = now
                if self._parent_gone():
                    return "the loop's process disappeared (killed?)", summary
            if n == 0 and m == 0 and k == 0:
                time.sleep(self._idle_sleep_s())

    def _idle_sleep_s(self) -> float:
        """How long to sleep with nothing to do: shorter while a remote command waits for
        its verdict (look for it sooner)."""
        return (VERDICT_SLEEP_S if self.net is not None and self.net.intake.waiting
                else IDLE_SLEEP_S)

    def _serve_sinks(self, now: float) -> int:
        """Poll the network (returns what it did: 0 if nothing) and service the
        recording."""
        k = self.net.poll(now) if self.net is not None else 0
        if self.recorder is not None:
            try:
                self.recorder.service(now)
                self.block.set_files(self.recorder.files)
            except Exception as exc:
                self._fail("recording write failed", exc)
        return k

    def _parent_gone(self) -> bool:
        """Whether the loop's process is gone (what it left is drained first)."""
        if os.getppid() == self.spec.parent_pid:
            return False
        self._drain_ticks()
        self._drain_events()
        return True

    def _finish(self, stop_reason: str, summary: JsonObject | None) -> None:
        """Close the network (token withdrawn, pending queries answered) and the
        Foxglove server, finish the recording with the summary."""
        if self.net is not None:  # token withdrawn, pending queries answered, closed
            self.net.close(stop_reason)
        if self.viewer is not None:
            self.viewer.close()
        if self.recorder is not None:
            try:
                self.recorder.finish(summary, stop_reason)
            except Exception as exc:
                self._fail("recording could not be finalised", exc)
                return
        if not self.failed:
            self.block.set(C_IO_STATE, IO_DONE)

    def _open_viewer(self) -> bool:
        """The Foxglove server (pamd.iohost.live); a taken port refuses, as Zenoh's does,
        before any file opens."""

        assert self.spec.viewer is not None
        # only a run with the live view pays for it (see LAZY_OWN in the layer test)
        from pamd.iohost.live import LiveView

        self.viewer = LiveView(self.spec.viewer, self.spec, self.block.t_start)
        err = self.viewer.open()
        if err is None:
            return True
        self.viewer = None
        self.block.set_error(f"foxglove: {err}")
        self.block.set(C_IO_STATE, IO_FAILED)
        self.failed = True
        if self.net is not None:
            self.net.close("the Foxglove server could not start")
        return False

    def _drain_ticks(self) -> int:
        ring = self.block.ticks
        avail = ring.available()
        if avail <= 0:
            return 0
        n = min(avail, BATCH)
        if self.net is not None and self.recorder is not None:
            # after the ring's head: a collection's begin is in by now
            self._control(self.net, self.recorder)
        start = ring.tail
        unpack, buf = self.rec_struct.unpack_from, ring.buf
        rows = [unpack(buf, ring.slot_offset(seq)) for seq in range(start, start + n)]
        ring.release(start + n)
        if self.net is not None:
            self.net.ticks(rows)
        if self.viewer is not None:
            self.viewer.ticks(rows)
        rec = self.recorder
        if rec is not None:
            if rec.t_start is None:
                rec.t_start = self.block.t_start()
            i_seg, half_period_s = rec.i_segment, 0.5 / self.spec.rate_hz
            try:
                for row in rows:
                    if row[i_seg] != rec.seg_seen:  # a step's file ends: its events first
                        self._drain_events((rec.t_start or 0.0) + row[1] - half_period_s)
                    rec.tick(row)
            except Exception as exc:
                self._fail("recording write failed", exc)
            else:
                self.block.set(C_RECORDED, rec.ticks)
            if rec.notices:
                self._notify(rec, rows[-1][1])
        self.last_tick = int(rows[-1][0])
        return n

    def _drain_events(self, before_t_s: float | None = None
                      ) -> tuple[int, JsonObject | None]:
        """Events into telemetry and the recording. With `before_t_s` (the first tick of
        a new step file is about to be written), every event older than that tick, so
        each goes into the file of the step it happened in (the loop writes a tick's
        events into their ring before its record; ticks are drained in batches first):
        the first newer one waits for the next drain."""
        ring = self.block.events
        n = 0
        summary = None
        while n < 64 or before_t_s is not None:
            ev = self._next_event
            self._next_event = None
            if ev is None:
                blob = ring.get_blob()
                if blob is None:
                    break
                ev = json.loads(blob)
            if before_t_s is not None and ev["t"] >= before_t_s:
                self._next_event = ev
                break
            n += 1
            name, data = ev["kind"], ev["data"]
            if name == "reply":
                self.reply_t = ev["t"]
                self.port.on_reply(data)
            if self.net is not None:
                self.net.event(ev["t"], name, data)
            if self.viewer is not None:
                self.viewer.event(ev["t"], name, data)
            if name == "summary":
                summary = data
                continue
            rec = self.recorder
            if rec is not None:
                if rec.t_start is None:
                    rec.t_start = self.block.t_start()
                try:
                    rec.event(ev["t"], name, data)
                except Exception as exc:
                    self._fail("recording write failed", exc)
        return n, summary

    def _control(self, net: NetNode, rec: Recorder) -> None:
        """Recording control from the daemon's main thread (pamd.wire.record.control)."""
        board = net.board
        while board is not None and (blob := board.control.get_blob()) is not None:
            rec.control(json.loads(blob))
        if rec.notices:
            self._notify(rec, net.last_t_s)

    def _notify(self, rec: Recorder, t_s: float) -> None:
        """The recorder's notices: to the daemon's main thread, and published."""
        for msg in rec.notices:
            if self.net is not None:
                self.net.notify_main(msg)
                self.net.event((self.block.t_start() or 0.0) + t_s, "collection", msg)
        rec.notices.clear()

    def _record_event(self, t_s: float, name: str, data: JsonObject) -> None:
        """An event of the io process's own (a command it refused) into the recording."""
        rec = self.recorder
        if rec is None:
            return
        if rec.t_start is None:
            rec.t_start = self.block.t_start()
        try:
            rec.event(t_s, name, data)
        except Exception as exc:
            self._fail("recording write failed", exc)

    def _run_script(self) -> None:
        while self.script and self.script[0][0] <= self.last_tick:
            _tick, verb, payload = self.script.pop(0)
            self.port.send(verb, payload, sender="script", on_verdict=self._scripted_verdict)

    def _scripted_verdict(self, data: JsonObject) -> None:
        """The verdict came back to the io process: say so in the recording."""
        if self.recorder is not None:
            try:
                self.recorder.event(self.reply_t, "verdict_received",
                                    {"by": "io process", **data})
            except Exception as exc:
                self._fail("recording write failed", exc)

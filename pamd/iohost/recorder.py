"""The recorder: tick records and events -> MCAP topics, one file per run (with
optional rotation), metadata and attachments stating what the run was.

Topics (they match the Zenoh key names):
  /pamd/<rig>/state/<muscle>  pamd_msgs/msg/MuscleState, cdr, one per muscle per tick
  /pamd/<rig>/loop            pamd_msgs/msg/LoopTiming,  cdr, one per tick
  /pamd/<rig>/events          pamd_msgs/msg/Event, json (jsonschema): every recorded event
                              of pamd.wire.declare.events (transitions, commands and verdicts,
                              lost records, recording notices, ...)
Log time: wall-clock ns of the tick's scheduled time in real time; with the virtual
clock, run start (wall clock) + tick x period, so the time axis is the rig's.

Experiment steps (the tick field `segment`, step + 1) get a file each: from the start
when the run is a collection (`pamd collect`: `RecordSpec.steps`), or, in a daemon
already recording, for the span of a collection started over the network
(`pamd.wire.record.control`: the recorder switches into the collection's directory at its first
step and back to an ordinary run file when `segment` returns to 0).
"""

from __future__ import annotations

import dataclasses
import json
import os
import struct
import time

from pamd.wire.declare import events
from pamd.wire.declare.jsonsafe import JsonObject, dumps, jsonsafe
from pamd.wire.record import cdr, control
from pamd.wire.record.mcapw import McapWriter
from pamd.wire.record.record_spec import RecordedRun, RecordSpec
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS

#: the recorded event's JSON schema, from the event registry (pamd.wire.declare.events)
EVENT_SCHEMA = events.json_schema()


def record_schemas() -> list[tuple[str, str, bytes]]:
    """(name, encoding, data) of the muscle state, loop and event schemas: the
    recording's, and the live Foxglove view's (pamd.iohost.live)."""
    return [
        (cdr.MUSCLE_SCHEMA_NAME, "ros2msg", cdr.schema_text(cdr.muscle_fields(), "pamd muscle "
                                                            "state, one per muscle per tick")),
        (cdr.LOOP_SCHEMA_NAME, "ros2msg", cdr.schema_text(cdr.loop_fields(), "pamd loop "
                                                          "timing, one per tick")),
        (cdr.EVENT_SCHEMA_NAME, "jsonschema", json.dumps(EVENT_SCHEMA).encode()),
    ]


def file_name(started_at: str, rig_id: str, run_name: str, segment: int,
              step: JsonObject | None = None) -> str:
    """`<time>_<rig>_<run>[_NN-<step>][_NNN].mcap`: an experiment step's files carry
    its number and name; a rotated file its segment number."""
    seg = f"_{segment:03d}" if segment else ""
    st = f"_{int(step['index']) + 1:02d}-{step['step']}" if step else ""
    return f"{started_at}_{rig_id}_{run_name}{st}{seg}.mcap"


class Recorder:
    """Encodes and writes; every OSError propagates to the io process (which reports
    it to the loop)."""

    def __init__(self, spec: RecordedRun) -> None:
        assert spec.record is not None
        self.spec = spec
        self.rs: RecordSpec = spec.record
        self.period_ns = round(1e9 / spec.rate_hz)
        self.n_loop = len(LOOP_FIELDS)
        self.n_mf = len(MUSCLE_FIELDS)
        self.rec_struct = struct.Struct(f"<{self.n_loop + self.n_mf * len(spec.muscles)}d")
        lf = cdr.loop_fields()
        mf = cdr.muscle_fields()
        self.loop_rec = cdr.compile_record(lf)
        self.mus_rec = cdr.compile_record(mf)
        self.loop_len = cdr.record_length(self.loop_rec)
        self.mus_len = cdr.record_length(self.mus_rec)
        self.loop_int = [i for i, (_n, t) in enumerate(lf) if t != "float64"]
        self.mus_int = [i for i, (_n, t) in enumerate(mf) if t != "float64"]
        self.schemas = record_schemas()
        self.t_start: float | None = None
        self.writer: McapWriter | None = None
        self.files: list[str] = []
        self.segment = 0
        self.ticks = 0
        self.events = 0
        self.last_tick = -1
        self.flush_ns = int(self.rs.flush_s * 1e9)
        self.chunk_max = self.rs.chunk_kb * 1024
        self.rotate_bytes = int(self.rs.rotate_mb * 1e6) if self.rs.rotate_mb else None
        self.rotate_ns = int(self.rs.rotate_s * 1e9) if self.rs.rotate_s else None
        self.max_bytes = int(self.rs.max_mb * 1e6) if self.rs.max_mb else None
        self.done_bytes = 0  # the run's finished files
        self.capped = False  # past max_bytes: ticks are no longer written
        self.chunk_t0 = -1  # log time of the open chunk's first tick
        self.chunk_opened = 0.0  # monotonic time the open chunk got its first message
        self.file_t0 = -1
        self.last_sync = time.monotonic()
        self.step_no = 0  # the step whose file is open: experiment step + 1, 0 outside
        self.i_segment = LOOP_FIELDS.index("segment")
        self.seg_seen = 0.0  # the tick field `segment` of the last tick
        self.base: RecordSpec = self.rs  # the run's own spec (a collection swaps rs)
        self.pending: JsonObject | None = None  # a collection announced (`begin`)
        self.coll: JsonObject | None = None  # the collection being recorded
        self.coll_files = self.coll_ticks = 0  # where it started in files and ticks
        self.notices: list[JsonObject] = []  # for the daemon (pamd.wire.record.control)
        self.name_suffix = ""  # "-2"... when the plain name was taken by an earlier run

    # -- files ------------------------------------------------------------------------
    def _create(self, name: str) -> tuple[McapWriter, str]:
        """Open a new file, never over an existing one: a run that starts within the same
        second as an earlier one (a quick virtual run, then its resume) takes a `-2`,
        `-3`... suffix, and keeps it for all its later files."""
        stem, ext = os.path.splitext(name)
        for n in range(1, 1000):
            suffix = self.name_suffix if n == 1 else f"-{n}"
            path = os.path.join(self.rs.dir, f"{stem}{suffix}{ext}")
            try:
                writer = McapWriter(path, self.rs.compression)
            except FileExistsError:
                continue
            self.name_suffix = suffix
            return writer, path
        raise FileExistsError(17, "no free file name", os.path.join(self.rs.dir, name))

    def open(self) -> str:
        os.makedirs(self.rs.dir, exist_ok=True)
        sp = self.spec
        name = file_name(self.rs.started_at, sp.rig_id, self.rs.run_name, self.segment,
                         self._step())
        w, path = self._create(name)
        self.writer = w
        self.files.append(path)
        w.start(profile="", library="pamd")
        sid = [w.add_schema(n, e, d) for n, e, d in self.schemas]
        self.ch_muscle = [
            w.add_channel(f"/pamd/{sp.rig_id}/state/{m}", "cdr", sid[0], {"muscle": m})
            for m in sp.muscles
        ]
        self.ch_loop = w.add_channel(f"/pamd/{sp.rig_id}/loop", "cdr", sid[1])
        self.ch_events = w.add_channel(f"/pamd/{sp.rig_id}/events", "json", sid[2])
        step = self._step()
        if step is not None:
            w.add_metadata("pamd.experiment", {k: str(v) for k, v in step.items()})
        for name, data in self.rs.metadata.items():
            data = dict(data)
            if name == "pamd":
                data["segment"] = str(self.segment)
                data["previous_file"] = os.path.basename(self.files[-2]) if self.segment else ""
            w.add_metadata(name, data)
        now = time.time_ns()
        for name, media, blob in self.rs.attachments:
            w.add_attachment(name, media, blob, now, now)
        self.file_t0 = -1
        self.chunk_t0 = -1
        w.sync()
        return path

    def _suffixed(self, name: str) -> str:
        stem, ext = os.path.splitext(name)
        return f"{stem}{self.name_suffix}{ext}"

    def _step(self) -> JsonObject | None:
        k = self.step_no - 1
        return self.rs.steps[k] if 0 <= k < len(self.rs.steps) else None

    def _rotate(self) -> None:
        assert self.writer is not None
        self.done_bytes += self.writer.pos
        self.writer.add_metadata("pamd.segment", {
            "segment": str(self.segment), "next_file": self._suffixed(file_name(
                self.rs.started_at, self.spec.rig_id, self.rs.run_name, self.segment + 1,
                self._step()))})
        self.writer.finish()
        self.segment += 1
        self.open()

    def _switch(self, rs: RecordSpec, step_no: int) -> None:
        """Finish the file and open the next one: the step's, or the run's again."""
        assert self.writer is not None
        self.done_bytes += self.writer.pos
        self.writer.finish()
        if rs is not self.rs:
            self.rs = rs
            self.name_suffix = ""
        self.step_no = step_no
        self.segment = 0
        self.open()

    # -- experiment steps and collections ------------------------------------------------
    def control(self, msg: JsonObject) -> None:
        """A control message of the daemon's main thread (pamd.wire.record.control)."""
        if msg.get("op") == control.BEGIN:
            self.pending = msg
        elif msg.get("op") == control.END:
            p = self.pending
            if p is not None and p["id"] == msg.get("id"):
                self.pending = None
                self.notices.append(control.notice(control.DROPPED, p))

    def _segment(self, seg: int, t_abs_s: float, log_ns: int) -> None:
        """The tick field `segment` changed: a step begins, or the plan has ended (0)."""
        self.seg_seen = seg
        if seg == 0:
            if self.coll is not None:
                self._end_collection(t_abs_s, log_ns)
            # else a plan of `pamd collect`: its last step's file keeps the rest of the run
            return
        if self.coll is None and self.pending is not None:
            self._begin_collection(seg, t_abs_s)
        elif self.rs.steps:
            self._switch(self.rs, seg)

    def _begin_collection(self, seg: int, t_abs_s: float) -> None:
        p = self.coll = self.pending
        assert p is not None
        self.pending = None
        self.event(t_abs_s, "collection", control.notice(control.BEGUN, p))
        self._switch(control.collection_spec(self.base, p), seg)
        self.coll_files, self.coll_ticks = len(self.files) - 1, self.ticks
        self.notices.append(control.notice(control.BEGUN, p))

    def _end_collection(self, t_abs_s: float, log_ns: int) -> None:
        p, self.coll = self.coll, None
        assert p is not None
        files = [os.path.basename(f) for f in self.files[self.coll_files:]]
        started = time.strftime("%Y%m%d-%H%M%S", time.localtime(log_ns / 1e9))
        self._switch(dataclasses.replace(self.base, started_at=started), 0)
        closed = control.notice(control.CLOSED, p, ticks=self.ticks - self.coll_ticks,
                                files=len(files))
        self.event(t_abs_s, "collection", dict(closed, files=files))
        self.notices.append(closed)

    # -- time -------------------------------------------------------------------------
    def log_ns_of(self, t_abs_s: float) -> int:
        return self.spec.wall0_ns + round((t_abs_s - self.spec.clock0_s) * 1e9)

    # -- the hot path -----------------------------------------------------------------
    def tick(self, v: tuple[float, ...]) -> None:
        if self.capped:
            return
        w = self.writer
        assert w is not None
        tick = int(v[0])
        if self.spec.virtual:
            log_ns = self.spec.wall0_ns + tick * self.period_ns
        else:
            log_ns = self.log_ns_of((self.t_start or 0.0) + v[1])
        if v[self.i_segment] != self.seg_seen:
            self._segment(int(v[self.i_segment]), (self.t_start or 0.0) + v[1], log_ns)
            w = self.writer
            assert w is not None
        if self.chunk_t0 < 0:
            self.chunk_t0 = log_ns
            self.chunk_opened = time.monotonic()
            if self.file_t0 < 0:
                self.file_t0 = log_ns
        seq = tick & 0xFFFFFFFF
        nl = self.n_loop
        vals = list(v[:nl])
        for i in self.loop_int:
            vals[i] = int(vals[i])
        w.add_record(self.ch_loop, log_ns, self.loop_rec.pack(
            5, self.loop_len, self.ch_loop, seq, log_ns, log_ns, cdr.CDR_LE, *vals))
        t_s = v[1]
        nm = self.n_mf
        mrec, mlen, mint = self.mus_rec, self.mus_len, self.mus_int
        for k, ch in enumerate(self.ch_muscle):
            b = nl + k * nm
            mv = [tick, t_s, *v[b:b + nm]]
            for i in mint:
                mv[i] = int(mv[i])
            w.add_record(ch, log_ns, mrec.pack(5, mlen, ch, seq, log_ns, log_ns, cdr.CDR_LE,
                                               *mv))
        self.ticks += 1
        self.last_tick = tick
        if log_ns - self.chunk_t0 >= self.flush_ns or len(w.chunk) >= self.chunk_max:
            self._close_chunk(log_ns)

    def _close_chunk(self, log_ns: int) -> None:
        w = self.writer
        assert w is not None
        w.close_chunk()
        self.chunk_t0 = -1
        if self.max_bytes is not None and self.done_bytes + w.pos >= self.max_bytes:
            self._cap(log_ns)
            return
        if (self.rotate_bytes and w.pos >= self.rotate_bytes) or (
                self.rotate_ns and self.file_t0 >= 0 and log_ns - self.file_t0 >= self.rotate_ns):
            self._rotate()

    def _cap(self, log_ns: int) -> None:
        """The run's files reached max_mb: no more ticks (events still go in)."""
        self.capped = True
        mb = self.max_bytes / 1e6 if self.max_bytes else 0.0
        t_abs = self.spec.clock0_s + (log_ns - self.spec.wall0_ns) / 1e9
        self.event(t_abs, "recording", {
            "message": f"recording stopped at its size cap of {mb:g} MB after "
                       f"{self.ticks} ticks; control goes on", "max_mb": mb})
        assert self.writer is not None
        self.writer.close_chunk()
        self.chunk_t0 = -1
        self.writer.sync()

    def event(self, t_abs_s: float, name: str, data: JsonObject) -> None:
        w = self.writer
        assert w is not None
        t0 = self.t_start if self.t_start is not None else t_abs_s
        log_ns = self.log_ns_of(t_abs_s)
        tick = round((t_abs_s - t0) * self.spec.rate_hz)
        body = dumps({"t_s": t_abs_s - t0, "tick": tick, "kind": name, "data": data})
        w.add_message(self.ch_events, log_ns, body.encode(), self.events)
        self.events += 1
        if self.chunk_t0 < 0:
            self.chunk_t0 = log_ns
            self.chunk_opened = time.monotonic()

    # -- housekeeping (once per io-loop pass) ------------------------------------------
    def service(self, now_mono: float) -> None:
        """Close a chunk that has been open for flush_s of wall time (a stalled or slow
        loop), and fsync every flush_s."""
        w = self.writer
        if w is None:
            return
        if w.chunk and now_mono - self.chunk_opened >= self.rs.flush_s:
            self._close_chunk(w.end_ns if self.chunk_t0 < 0 else self.chunk_t0)
        if now_mono - self.last_sync >= self.rs.flush_s:
            self.last_sync = now_mono
            self.writer.sync()  # type: ignore[union-attr]

    def finish(self, summary: JsonObject | None, stop_reason: str) -> None:
        w = self.writer
        if w is None:
            return
        meta = {"io_stop": stop_reason, "ticks_recorded": str(self.ticks),
                "last_tick": str(self.last_tick), "events_recorded": str(self.events),
                "files": json.dumps([os.path.basename(f) for f in self.files]),
                "capped": "true" if self.capped else "false"}
        if summary:
            for k, v in summary.items():
                meta[k] = v if isinstance(v, str) else json.dumps(jsonsafe(v))
        w.add_metadata("pamd.summary", meta)
        w.finish()
        self.writer = None

    def abandon(self) -> None:
        if self.writer is not None:
            self.writer.abandon()
            self.writer = None

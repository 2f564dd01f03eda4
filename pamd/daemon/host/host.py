"""The daemon's main-process side of telemetry: writes the status snapshot into the
board at `telemetry.status_hz`, and does the work of the commands that need the main
thread (`collect`: read and check the plan file, make the collection's directory and
manifest and tell the io process's recorder (`pamd.daemon.host.collections`), then queue
it; `model`: load, check and compile the model file, then queue it) before the loop
gives its verdict, which goes back to the io process by id. It also takes the io
process's notices (a collection's files closed) and writes a collection's manifest
when its plan has ended.

Runs in `Daemon.service()` (the main thread, every few tens of ms); never in the
loop's thread.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from concurrent.futures import Future
from dataclasses import dataclass

from pamd.daemon.host.collections import Collection, Collections
from pamd.daemon.host.parts import HostParts
from pamd.daemon.host.snapshot import StatusBuilder, recording_status
from pamd.loop.commands import Command, named_files, parse_command
from pamd.loop.commands.model_file import ModelSource, prepare_model_from
from pamd.loop.commands.offload import Preparer, warm_up
from pamd.loop.commands.plan_file import read_plan
from pamd.loop.experiment.plan import Plan
from pamd.wire.board import Board
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.status import jsonsafe
from pamd.wire.verbs.args import args_for_record

log = logging.getLogger("pamd")

#: collect/model commands whose files are being read at once, at most (more are refused)
MAX_PREPARING = 4


@dataclass(frozen=True)
class PlanArgs:
    """A `collect` whose plan was read and checked here (the loop records every
    field but `plan`)."""

    plan_file: str
    start_step: int
    plan: Plan


class _Pending:
    def __init__(self) -> None:
        self.verdict: JsonObject | None = None
        self.collection: Collection | None = None  # a collect's, until its verdict

    def set(self, verdict: JsonObject) -> None:  # the loop's thread
        self.verdict = verdict


class NetHost:
    def __init__(self, parts: HostParts, board: Board, status_hz: float,
                 record_dir: str | None = None) -> None:
        """`parts`: what it uses of the daemon (never the daemon); `record_dir`: where
        the daemon records (None: it does not, and a collect is refused)."""
        self.d = parts
        self.board = board
        self.period_s = 1.0 / status_hz
        self.collections = Collections(parts, record_dir, board.control.put_blob)
        self.builder = StatusBuilder(parts.ctrl, parts.loop, parts.config,
                                     lambda: recording_status(parts.io),
                                     self.collections.describe)
        self.last_t = -1e9
        self.pending: dict[int, _Pending] = {}
        self.outbox: list[bytes] = []  # replies waiting for room in the ring
        # collect/model: their files read in a child process (pamd.loop.commands.offload),
        # waited for by a worker thread, taken up by service()
        self.preparer = Preparer()
        self.preparing: list[tuple[_Request, Future[Command]]] = []
        cfg = parts.cfg
        if any(named_files.configured_dir(cfg, k) for k in ("plans_dir", "models_dir")):
            # the file reader started now, not by the first such command (whose
            # verdict has a deadline, the reader's start included); in a worker
            # thread, so that the daemon's start-up does not wait for it
            self.preparer.submit(warm_up)

    def service(self) -> None:
        now = time.monotonic()
        if now - self.last_t >= self.period_s:
            self.last_t = now
            self.write_status(now)
        while (blob := self.board.requests.get_blob()) is not None:
            self._request(blob)
        self._take_prepared()
        for rid, p in list(self.pending.items()):
            if p.verdict is not None:
                del self.pending[rid]
                try:
                    verdict = (p.verdict if p.collection is None else
                               self.collections.verdict(p.collection, p.verdict))
                except Exception as exc:  # the daemon never dies of a request
                    log.exception("the verdict of request %d", rid)
                    verdict = {**p.verdict, "warning": f"the collection's bookkeeping "
                               f"failed ({exc.__class__.__name__}); see the daemon's log"}
                self._reply(rid, verdict)
        while self.outbox and self.board.replies.put_blob(self.outbox[0]):
            self.outbox.pop(0)
        self.collections.service()

    def close(self, reason: str) -> None:
        """The io process has ended: a collection still open gets its manifest."""
        self.preparer.close()
        self.collections.close(reason)

    def write_status(self, now: float | None = None) -> None:
        try:
            snap = self.builder.build(time.monotonic() if now is None else now)
            blob = json.dumps(snap, separators=(",", ":"), default=str).encode()
        except Exception as exc:  # never let status kill the daemon's main thread
            blob = json.dumps({"error": f"status failed: {exc!r}"}).encode()
        if not self.board.write_status(blob):
            self.board.write_status(json.dumps({"error": "status too large"}).encode())

    def stopping(self, reason: str) -> None:
        self.board.set_stopping(reason)
        self.write_status()

    # -- commands that need this thread ----------------------------------------------
    def _reply(self, rid: int, verdict: JsonObject) -> None:
        blob = json.dumps({"id": rid, "verdict": jsonsafe(verdict)}, default=str).encode()
        cap = self.board.replies.slot_bytes - 4
        if len(blob) > cap:
            short = {"ok": verdict.get("ok", False), "error": verdict.get("error"),
                     "note": "verdict truncated"}
            blob = json.dumps({"id": rid, "verdict": short}, default=str).encode()
        self.outbox.append(blob)

    def _request(self, blob: bytes) -> None:
        try:
            req = json.loads(blob)
            if "notice" in req:  # the io process's (pamd.wire.record.control)
                self.collections.notice(req["notice"])
                return
            rid = int(req["id"])
        except (ValueError, KeyError, TypeError, RecursionError):
            return
        r = _Request(rid, str(req.get("verb")), req.get("payload"),
                     str(req.get("sender", "zenoh")), str(req.get("user", "")), _Pending())
        try:
            cmd = parse_command(r.verb, r.payload, sender=r.sender, user=r.user,
                                reply=r.p.set)
            if r.verb in ("collect", "model"):  # a file: read in a child process
                if len(self.preparing) >= MAX_PREPARING:  # a flood reads no more files
                    raise CommandRefused(f"{r.verb}: the daemon is reading "
                                         f"{len(self.preparing)} files already; try again")
                self.preparing.append((r, self.preparer.submit(self._files, cmd)))
                return
        except Exception as exc:
            self._refuse(r, exc)
            return
        self._queue(r, cmd)

    def _take_prepared(self) -> None:
        """The collect/model commands whose files have been read: on to the loop."""
        waiting = []
        for r, fut in self.preparing:
            if not fut.done():
                waiting.append((r, fut))
                continue
            try:
                cmd = fut.result()
                if r.verb == "collect":
                    a = cmd.args
                    r.p.collection = self.collections.prepare(
                        a.plan, a.plan_file, a.start_step, r.sender, r.user, a.collection)
                    cmd = Command("collect", PlanArgs(a.plan_file, a.start_step, a.plan),
                                  r.p.set, r.sender, r.user)
            except Exception as exc:
                self._refuse(r, exc)
                continue
            self._queue(r, cmd)
        self.preparing = waiting

    def _queue(self, r: _Request, cmd: Command) -> None:
        self.pending[r.rid] = r.p
        self.d.mailbox.put(cmd)

    def _refuse(self, r: _Request, exc: BaseException) -> None:
        if isinstance(exc, CommandRefused):
            error = str(exc)
        else:  # the daemon never dies of a request
            log.error("%s request from %s: %s", r.verb, r.sender, exc, exc_info=exc)
            error = (f"{r.verb}: refused: it failed while being prepared "
                     f"({exc.__class__.__name__}); the daemon goes on")
        verdict = {"ok": False, "error": error}
        try:
            ctrl = self.d.ctrl
            self.d.summary.event(ctrl.now, "command", {
                "verb": r.verb, "args": args_for_record(r.payload), "sender": r.sender,
                "user": r.user, "by": "daemon", **verdict})
        finally:
            self._reply(r.rid, verdict)

    def _files(self, cmd: Command) -> Command:
        """In a worker thread: the command's file read, parsed and checked in a child
        process (collect: the plan; model: the model, then compiled here), only by name
        from the directory the config allows. A collect comes back as a
        `_ReadPlan` for `_take_prepared` (its directory is made in the main thread)."""
        cfg = self.d.cfg
        a = cmd.args
        if cmd.verb == "collect":
            plan, path = read_plan(a.plan_file, cfg)
            return dataclasses.replace(cmd, args=_ReadPlan(path, a.start_step, plan,
                                                           a.collection))
        path = named_files.resolve(a.file, named_files.configured_dir(cfg, "models_dir"),
                                   "model", "models_dir")
        return prepare_model_from(dataclasses.replace(cmd, args=dataclasses.replace(
            a, file=path)), cfg, ModelSource(path, a.file, named=True))


@dataclass(frozen=True)
class _Request:
    rid: int
    verb: str
    payload: object
    sender: str
    user: str
    p: _Pending


@dataclass(frozen=True)
class _ReadPlan:
    plan_file: str
    start_step: int
    plan: Plan
    collection: str | None


__all__ = ["NetHost", "PlanArgs", "read_plan"]

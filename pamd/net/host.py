"""The daemon's main-process side of telemetry: writes the status snapshot into the
board at `telemetry.status_hz`, and does the work of the commands that need the main
thread (`collect`: read and check the plan file, make the collection's directory and
manifest and tell the io process's recorder (`pamd.net.collections`), then queue
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
from dataclasses import dataclass
from typing import Any

from pamd.commands import Command, named_files, parse_command, prepare_command
from pamd.commands.schema import args_for_record
from pamd.config.loader import LoadedConfig
from pamd.errors import CommandRefused, PamdError
from pamd.experiment.plan import Plan, parse_plan
from pamd.net.board import Board
from pamd.net.collections import Collection, Collections
from pamd.net.seams import DaemonView
from pamd.net.status import StatusBuilder, jsonsafe

log = logging.getLogger("pamd")


@dataclass(frozen=True)
class PlanArgs:
    """A `collect` whose plan was read and checked here (the loop records every
    field but `plan`)."""

    plan_file: str
    start_step: int
    plan: Any


class _Pending:
    def __init__(self) -> None:
        self.verdict: dict[str, Any] | None = None
        self.collection: Collection | None = None  # a collect's, until its verdict

    def set(self, verdict: dict[str, Any]) -> None:  # the loop's thread
        self.verdict = verdict


class NetHost:
    def __init__(self, daemon: DaemonView, board: Board, status_hz: float,
                 record_dir: str | None = None) -> None:
        """`record_dir`: where the daemon records (None: it does not, and a collect is
        refused)."""
        self.d = daemon
        self.board = board
        self.period_s = 1.0 / status_hz
        self.collections = Collections(daemon, record_dir, board.control.put_blob)
        self.builder = StatusBuilder(daemon, self.collections.describe)
        self.last_t = -1e9
        self.pending: dict[int, _Pending] = {}
        self.outbox: list[bytes] = []  # replies waiting for room in the ring

    def service(self) -> None:
        now = time.monotonic()
        if now - self.last_t >= self.period_s:
            self.last_t = now
            self.write_status(now)
        while (blob := self.board.requests.get_blob()) is not None:
            self._request(blob)
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
    def _reply(self, rid: int, verdict: dict[str, Any]) -> None:
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
            if "notice" in req:  # the io process's (pamd.record.control)
                self.collections.notice(req["notice"])
                return
            rid = int(req["id"])
        except (ValueError, KeyError, TypeError, RecursionError):
            return
        verb, payload = str(req.get("verb")), req.get("payload")
        sender, user = str(req.get("sender", "zenoh")), str(req.get("user", ""))
        p = _Pending()
        try:
            cmd = self._prepare(verb, payload, sender, user, p)
        except CommandRefused as exc:
            error = str(exc)
        except Exception as exc:  # the daemon never dies of a request
            log.exception("%s request from %s", verb, sender)
            error = (f"{verb}: refused: it failed while being prepared "
                     f"({exc.__class__.__name__}); the daemon goes on")
        else:
            self.pending[rid] = p
            self.d.mailbox.put(cmd)
            return
        verdict = {"ok": False, "error": error}
        try:
            ctrl = self.d.ctrl
            self.d.summary.event(ctrl.now, "command", {
                "verb": verb, "args": args_for_record(payload), "sender": sender,
                "user": user, "by": "daemon", **verdict})
        finally:
            self._reply(rid, verdict)

    def _prepare(self, verb: str, payload: object, sender: str, user: str,
                 p: _Pending) -> Command:
        """The command ready for the loop, its file read and checked here (collect: the
        plan; model: the model), only by name from the directory the config allows."""
        cfg = self.d.cfg
        cmd = parse_command(verb, payload, sender=sender, user=user, reply=p.set)
        if verb == "collect":
            a = cmd.args
            plan, path = read_plan(a.plan_file, cfg)
            p.collection = self.collections.prepare(plan, path, a.start_step, sender, user,
                                                    a.collection)
            return Command("collect", PlanArgs(path, a.start_step, plan), p.set, sender,
                           user)
        if verb == "model":
            a = cmd.args
            path = named_files.resolve(a.file, named_files.configured_dir(cfg, "models_dir"),
                                       "model", "models_dir")
            nf = named_files.read_limited(path, a.file, "model", named_files.MODEL_MAX_BYTES)
            return prepare_command(dataclasses.replace(cmd, args=dataclasses.replace(
                a, file=path)), cfg, nf.text.encode("utf-8"))
        return cmd


def read_plan(name: str, cfg: LoadedConfig) -> tuple[Plan, str]:
    """A remote collect's plan: file `name` in `telemetry.plans_dir`, within the limits
    (`pamd.commands.named_files`), parsed and checked against the rig; the refusal
    names file, line and key and never quotes the file."""

    try:
        path = named_files.resolve(name, named_files.configured_dir(cfg, "plans_dir"),
                                   "plan", "plans_dir")
        nf = named_files.read_limited(path, name, "plan", named_files.PLAN_MAX_BYTES)
    except CommandRefused as exc:
        raise CommandRefused(f"collect: plan refused: {exc}") from None
    try:
        return parse_plan(nf.text, path, cfg), path
    except PamdError as exc:
        raise CommandRefused(f"collect: plan refused: "
                             f"{named_files.issues_text(exc, name)}") from None
    except RecursionError:
        raise CommandRefused(f"collect: plan refused: {name!r} is nested too deep") from None

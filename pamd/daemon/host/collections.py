"""A collection started over the network (`pamd cmd collect --plan-file PLAN` to a
running daemon): the same result as `pamd collect PLAN`, one MCAP file per step (same
names, same `pamd.experiment` metadata) and a `manifest.json`, in a directory of its
own under the daemon's recording directory: `<recording dir>/<plan>-<YYYYmmdd-HHMMSS>/`.

- **The directory is the daemon's choice**, never the request's: clients are not
  authenticated (a client can claim any user), so no request names a path on the rig
  PC. The collect reply says where the collection goes.
- **`start_step` > 0 resumes**, as `pamd collect --resume DIR` does: the newest
  collection of the same plan (same name, same steps) under the recording directory
  whose manifest has an unfinished step takes the new files, and its manifest the new
  run; `collection` names one instead (its directory name, never a path). With none
  to resume, the command is refused (start_step 0 starts a new one).
- **A daemon that does not record refuses** a collect: a plan run without its files
  is hours of a rig for nothing, and the daemon has nowhere it was told it may write.
- **When the plan ends** (done, aborted, or failed by a fault) the io process closes
  the last step's file and goes back to an ordinary run file in its own directory;
  then the manifest is written, recording the run as `pamd collect` does
  (`Manifest.record_run`, with who asked). A daemon that stops first writes it as it
  closes. The manifest is also written when the loop takes the plan and each time a
  step ends, so a crash leaves one to resume from; one still stale is brought in line
  with the step files' own metadata when the collection is resumed
  (`Manifest.reconcile`).

Everything here runs in the daemon's main thread (`NetHost.service`, and the io
session's close): the directory, the manifest (file I/O), and the control message that
tells the io process's recorder where the steps go (`pamd.wire.record.control`), sent before
the plan reaches the loop. The loop's thread does none of it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

from pamd.daemon.host.parts import HostParts
from pamd.loop.experiment.manifest import Manifest, collection_name, step_records
from pamd.loop.experiment.plan import Plan
from pamd.loop.experiment.sequencer import Sequencer, running_plan
from pamd.loop.experiment.timeline import simulated_loads, timeline
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import CommandRefused, ConfigError, PamdError
from pamd.wire.record import control

log = logging.getLogger("pamd")


@dataclass
class Collection:
    """One collection, from the request to its manifest."""

    id: int
    dir: str
    plan: Plan
    start: int
    manifest: Manifest
    created: bool  # its directory was made for it (removed again if the loop refuses)
    before: frozenset[str]  # what the directory held already (a resumed collection)
    sender: str
    user: str
    tick0: int
    faults0: int
    lost0: int
    seq: Sequencer | None = None  # the loop's sequencer, once the loop took the plan
    end_sent: bool = False
    closed: bool = False  # the io process has closed its files
    steps_saved: int = 0  # finished steps the manifest on disk knows of
    save_due: bool = False  # the loop took the plan: the manifest is to be written
    ticks: int | None = None  # tick records its files hold

    def describe(self) -> JsonObject:
        return {"collection": self.dir, "manifest": self.manifest.path,
                "resumed": not self.created, "start_step": self.start}


class Collections:
    """The daemon's collections started over the network, one at a time."""

    def __init__(self, parts: HostParts, record_dir: str | None,
                 send: Callable[[bytes], bool]) -> None:
        """`parts`: what it uses of the daemon (the config, the run's note, the
        recording's state, the controller's plan and counters, the events); `send`:
        into the board's control ring."""
        self.d = parts
        self.record_dir = os.path.abspath(record_dir) if record_dir else None
        self.send = send  # into the board's control ring (main -> io)
        self.active: Collection | None = None
        self.outbox: list[bytes] = []  # control messages waiting for room
        self.next_id = 1

    # -- the request ----------------------------------------------------------------------
    def prepare(self, plan: Plan, plan_file: str, start: int, sender: str,
                user: str, name: str | None = None) -> Collection:
        """Before the plan goes to the loop: its directory and manifest, and the io
        process told. CommandRefused (and nothing left behind) if it cannot be."""
        if self.record_dir is None:
            raise CommandRefused(
                "collect: this daemon does not record (started with --no-record, or no "
                "recording.dir), so the plan would leave no files; restart it with "
                "--record DIR, or run pamd collect on the rig PC")
        io = self.d.io
        if io is not None and io.failure is not None:
            raise CommandRefused(f"collect: the recording has stopped "
                                 f"({io.failure['reason']}); restart the daemon")
        if self.active is not None:
            raise CommandRefused(f"collect: collection {self.active.dir} is still running")
        if name is not None and start == 0:
            raise CommandRefused("collect: a collection is named only to resume it; add "
                                 "start_step (the first unfinished step)")
        if start == 0:
            directory, created = self._new_dir(plan), True
        elif name is not None:
            directory, created = self._named(plan, name), False
        else:
            directory, created = self._resumable(plan, start), False
        try:
            coll = self._announce(plan, plan_file, start, directory, created, sender, user)
        except BaseException:
            if created:
                with contextlib.suppress(OSError):
                    os.rmdir(directory)
            raise
        self.active = coll
        return coll

    def _announce(self, plan: Plan, plan_file: str, start: int, directory: str,
                  created: bool, sender: str, user: str) -> Collection:
        cfg = self.d.cfg
        try:
            manifest = (Manifest.new(directory, plan, plan_file, cfg) if created
                        else Manifest.load(directory, reconcile=True))
            before = frozenset(os.listdir(directory))
        except (OSError, PamdError) as exc:
            raise CommandRefused(f"collect: {exc}") from None
        cid, self.next_id = self.next_id, self.next_id + 1
        steps = step_records(plan, timeline(plan, cfg, simulated_loads(cfg, plan)))
        note = "; ".join(n for n in (self.d.note, plan.metadata.notes) if n)
        meta = {"pamd": {"run_name": plan.name, "note": note},
                "pamd.profile": {"plan": plan.name, "plan_file": os.path.abspath(plan_file)},
                "pamd.collection": {"dir": directory, "manifest": manifest.path,
                                    "start_step": str(start), "requested_by": sender,
                                    "user": user}}
        blob = control.begin_message(cid, directory, plan.name, time.strftime(
            "%Y%m%d-%H%M%S"), steps, meta)
        try:
            sent = self.send(blob)
        except ValueError:  # larger than a slot of the control ring
            raise CommandRefused(f"collect: plan {plan.name!r} has too many steps to hand "
                                 "to the recorder; split it") from None
        if not sent:
            raise CommandRefused("collect: the io process is busy; try again")
        ctrl = self.d.ctrl
        return Collection(cid, directory, plan, start, manifest, created, before, sender,
                          user, ctrl.tick_no, ctrl.supervisor.fault_count,
                          self.d.loop.lost_records)

    def _new_dir(self, plan: Plan) -> str:
        assert self.record_dir is not None
        stem = os.path.join(self.record_dir, collection_name(plan))
        try:
            os.makedirs(self.record_dir, exist_ok=True)
            for n in range(1, 100):
                path = stem if n == 1 else f"{stem}-{n}"
                with contextlib.suppress(FileExistsError):
                    os.mkdir(path)
                    return path
        except OSError as exc:
            raise CommandRefused(f"collect: cannot create the collection's directory: "
                                 f"{exc}") from None
        raise CommandRefused(f"collect: no free directory name for {stem}")

    def _named(self, plan: Plan, name: str) -> str:
        """The collection `name` (a directory under the recording directory, never a
        path) if it is an unfinished collection of this plan."""
        assert self.record_dir is not None
        if name in ("", ".", "..") or os.sep in name or (os.altsep and os.altsep in name):
            raise CommandRefused(f"collect: collection {name!r} must be a directory name "
                                 "under the daemon's recording directory, not a path")
        path = os.path.join(self.record_dir, name)
        try:
            m = Manifest.load(path, reconcile=True)
        except (ConfigError, OSError) as exc:
            raise CommandRefused(f"collect: collection {name!r}: {exc}") from None
        if m.plan_name != plan.name or [s["name"] for s in m.data["steps"]] != [
                s.name for s in plan.steps]:
            raise CommandRefused(f"collect: collection {name!r} holds plan "
                                 f"{m.plan_name!r} with other steps, not {plan.name!r}")
        if m.first_unfinished() is None:
            raise CommandRefused(f"collect: collection {name!r} is finished; nothing to "
                                 "resume")
        return path

    def _resumable(self, plan: Plan, start: int) -> str:
        """The newest unfinished collection of this plan (same steps) to resume."""
        assert self.record_dir is not None
        names = [s.name for s in plan.steps]
        best: tuple[float, str] | None = None
        with contextlib.suppress(OSError):
            for entry in os.scandir(self.record_dir):
                path = os.path.join(entry.path, "manifest.json")
                if not entry.is_dir() or not os.path.isfile(path):
                    continue
                try:
                    m = Manifest.load(entry.path)
                except ConfigError:
                    continue
                if (m.plan_name == plan.name and m.first_unfinished() is not None
                        and [s["name"] for s in m.data["steps"]] == names):
                    mtime = os.path.getmtime(path)
                    if best is None or mtime > best[0]:
                        best = (mtime, entry.path)
        if best is None:
            raise CommandRefused(
                f"collect: start_step {start} resumes a collection, but no unfinished "
                f"collection of plan {plan.name!r} (with these steps) is under "
                f"{self.record_dir}; start_step 0 starts a new one")
        return best[1]

    # -- the loop's verdict ----------------------------------------------------------------
    def verdict(self, coll: Collection, verdict: JsonObject) -> JsonObject:
        """The reply to the collect: the loop's verdict and where the collection goes."""
        if not verdict.get("ok"):  # nothing began: the recorder forgets it
            self._queue(control.end_message(coll.id))
            if coll.created:
                with contextlib.suppress(OSError):
                    os.rmdir(coll.dir)
            if self.active is coll:
                self.active = None
            return verdict
        coll.seq = running_plan(self.d.ctrl)
        # written now (a process crash finds it), made durable by service() after the
        # reply has gone: an fsync can take seconds on a disk busy with recordings, and
        # the verdict has a deadline
        try:
            coll.manifest.save(durable=False)
        except OSError as exc:
            log.error("collection %s: cannot write its manifest: %s", coll.dir, exc)
        coll.save_due = True
        self._event("started", coll, plan=coll.plan.name, sender=coll.sender, user=coll.user)
        log.info("collection %s: plan %s from step %d (requested by %s %s)", coll.dir,
                 coll.plan.name, coll.start + 1, coll.sender, coll.user)
        return {**verdict, **coll.describe()}

    # -- the io process's notices, the plan's end ------------------------------------------
    def notice(self, msg: JsonObject) -> None:
        c = self.active
        if c is not None and msg.get("id") == c.id and msg.get("what") in (control.CLOSED,
                                                                          control.DROPPED):
            c.closed = True
            c.ticks = int(msg.get("ticks", 0))

    def service(self) -> None:
        """Every pass of the main thread: the manifest once the plan has ended and the io
        process has closed its files (or can no longer: the recording failed)."""
        while self.outbox and self.send(self.outbox[0]):
            self.outbox.pop(0)
        c = self.active
        if c is None or c.seq is None:
            return
        finished = list(c.seq.finished_steps)  # appended by the loop's thread
        if len(finished) > c.steps_saved:  # a step has ended: the manifest says so now
            c.steps_saved = len(finished)
            c.save_due = c.manifest.steps_finished(finished, c.start) or c.save_due
        if c.save_due:
            c.save_due = False
            try:
                c.manifest.save()
            except OSError as exc:
                log.error("collection %s: cannot write its manifest: %s", c.dir, exc)
        if c.seq.outcome and not c.end_sent:
            c.end_sent = True  # a collection whose first step never began is dropped
            self._queue(control.end_message(c.id))
        io = self.d.io
        if c.closed or (c.seq.outcome and io is not None and io.failure is not None):
            self._finish(c)

    def close(self, reason: str) -> None:
        """The io process has ended (the daemon closes): what is left is written."""
        c = self.active
        if c is None:
            return
        seq = running_plan(self.d.ctrl)
        if c.seq is None and seq is not None and seq.plan is c.plan:
            c.seq = seq  # taken by the loop, its verdict not yet seen
        if c.seq is None:  # the loop never took the plan
            if c.created:
                with contextlib.suppress(OSError):
                    os.rmdir(c.dir)
            self.active = None
            return
        # no event: the recording is finalised and the rings are gone
        self._finish(c, None if c.seq.outcome else f"aborted: the daemon stopped ({reason})",
                     event=False)

    def _finish(self, c: Collection, outcome: str | None = None, event: bool = True) -> None:
        self.active = None
        ctrl = self.d.ctrl
        try:
            files = sorted(f for f in os.listdir(c.dir) if f.endswith(".mcap")
                           and f not in c.before)
            result = {"recording": {"files": files},
                      "faults": ctrl.supervisor.faults_since(c.faults0),
                      "ticks": c.ticks if c.ticks is not None else ctrl.tick_no - c.tick0,
                      "lost_records": self.d.loop.lost_records - c.lost0}
            c.manifest.record_run(c.seq, result, c.start, outcome,
                                  {"requested_by": c.sender, "user": c.user})
            c.manifest.save()
        except Exception as exc:  # never let the manifest stop the daemon's main thread
            log.error("collection %s: cannot write its manifest: %s", c.dir, exc)
            return
        outcome = c.manifest.data["runs"][-1]["outcome"]
        if event:
            self._event("ended", c, outcome=outcome, files=len(files))
        log.info("collection %s: %s; %d file(s); manifest %s", c.dir, outcome, len(files),
                 c.manifest.path)

    # -- helpers ------------------------------------------------------------------------------
    def _queue(self, blob: bytes) -> None:
        self.outbox.append(blob)
        while self.outbox and self.send(self.outbox[0]):
            self.outbox.pop(0)

    def _event(self, what: str, c: Collection, **data: JsonValue) -> None:
        """Into the recording (the run file) and onto the events key."""
        self.d.summary.event(self.d.ctrl.now, "collection",
                             {"what": what, "id": c.id, **c.describe(), **data})

    def describe(self) -> JsonObject | None:
        """For the status snapshot: the collection running, if any."""
        c = self.active
        return c.describe() if c is not None and c.seq is not None else None

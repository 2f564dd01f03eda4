"""The manifest of a collection: the plan, each step's status and files, and every
run that worked on it. `--resume` reads it to continue from the first unfinished
step. Written atomically, so a crash never leaves half a manifest, and again each
time a step ends (`steps_finished`), so a crash loses at most the step it stopped in;
one left stale all the same (the main process killed between a step's end and the
write) is brought in line with the step files' own metadata (`reconcile`,
`pamd.loop.experiment.stepfiles`) by `pamd inspect`, `--resume` and a remote resume.

Also what `pamd collect` and a collection started over the network
(`pamd.daemon.host.collections`) share: the collection directory's name and what each step's
recording file states (`step_records`)."""

from __future__ import annotations

import json
import os
import time

from pamd.config.loader import LoadedConfig
from pamd.loop.experiment.plan import Plan
from pamd.loop.experiment.sequencer import Sequencer
from pamd.loop.experiment.stepfiles import read_step_file
from pamd.loop.experiment.timeline import StepLine
from pamd.wire.atomic import atomic_text
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ConfigError, ConfigIssue
from pamd.wire.version import __version__

FORMAT, VERSION = "pamd-collection", 1


def collection_name(plan: Plan, wall_s: float | None = None) -> str:
    """`<plan>-<YYYYmmdd-HHMMSS>`: a new collection's directory (local time)."""
    return f"{plan.name}-{time.strftime('%Y%m%d-%H%M%S', time.localtime(wall_s))}"


def step_records(plan: Plan, lines: list[StepLine]) -> tuple[JsonObject, ...]:
    """Per step, what its recording file is named after and states as `pamd.experiment`
    metadata: the plan, the step's name and index, and the load it runs under."""
    return tuple({"step": s.name, "index": i, "plan": plan.name, "load_kg": lines[i].load_kg}
                 for i, s in enumerate(plan.steps))


class Manifest:
    def __init__(self, directory: str, data: JsonObject) -> None:
        self.directory = directory
        self.data = data

    @property
    def path(self) -> str:
        return os.path.join(self.directory, "manifest.json")

    @property
    def plan_name(self) -> str:
        return str(self.data["plan"]["name"])

    @classmethod
    def new(cls, directory: str, plan: Plan, plan_file: str, cfg: LoadedConfig) -> Manifest:
        with open(plan_file, encoding="utf-8") as fh:
            plan_text = fh.read()
        return cls(directory, {
            "format": FORMAT, "version": VERSION, "pamd": __version__,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "plan": {"name": plan.name, "file": os.path.abspath(plan_file), "text": plan_text,
                     "muscle": plan.muscle, "metadata": vars(plan.metadata)},
            "rig": {"config": os.path.abspath(cfg.path), "sha256": cfg.sha256,
                    "rig_id": cfg.rig.rig_id},
            "steps": [{"index": i, "name": s.name, "load_kg": s.load_kg, "status": "pending",
                       "files": []} for i, s in enumerate(plan.steps)],
            "runs": [],
        })

    @classmethod
    def load(cls, directory: str, reconcile: bool = False) -> Manifest:
        """The manifest in `directory`; with `reconcile`, brought in line with its step
        files and saved if it was stale (what a resume does)."""
        m = cls._load(directory)
        if reconcile and m.reconcile():
            m.save()
        return m

    @classmethod
    def _load(cls, directory: str) -> Manifest:
        path = os.path.join(directory, "manifest.json")
        try:
            with open(path, encoding="utf-8") as fh:
                data = json.load(fh)
        except (OSError, ValueError) as exc:
            raise ConfigError([ConfigIssue(path, None, "", "a pamd collection manifest",
                                           str(exc))]) from None
        if data.get("format") != FORMAT or data.get("version") != VERSION:
            raise ConfigError([ConfigIssue(path, None, "format", f"{FORMAT} v{VERSION}",
                                           f"{data.get('format')} v{data.get('version')}")])
        return cls(directory, data)

    def _tag(self, s: JsonObject) -> str:
        return f"_{s['index'] + 1:02d}-{s['name']}"

    def _on_disk(self) -> list[str]:
        try:
            return sorted(f for f in os.listdir(self.directory) if f.endswith(".mcap"))
        except OSError:
            return []

    def steps_finished(self, finished: list[str], start: int = 0) -> bool:
        """Mark the steps named in `finished` done, with their files (named after the
        step, in the directory): what the daemon saves as each step ends. True if
        anything changed."""
        names = set(finished)
        on_disk = self._on_disk()
        changed = False
        for s in self.data["steps"][start:]:
            if s["name"] in names and s["status"] != "done":
                own = [f for f in on_disk if self._tag(s) in f]
                s["files"] = sorted(set(s["files"]) | set(own))
                s["status"] = "done"
                changed = True
        return changed

    def reconcile(self) -> list[str]:
        """Bring each step's status and files in line with what the step files in the
        directory say of themselves (their `pamd.experiment` metadata and
        `step_finished` event); returns what changed (empty: the manifest was up to
        date). Only files of steps not yet done, or named by no step, are read."""
        steps = self.data["steps"]
        named = {f: s for s in steps for f in s["files"]}
        changes: list[str] = []
        for f in self._on_disk():
            owner = named.get(f)
            if owner is not None and owner["status"] == "done":
                continue
            sf = read_step_file(os.path.join(self.directory, f))
            if sf is None or sf.plan != self.plan_name or not 0 <= sf.index < len(steps):
                continue
            s = steps[sf.index]
            if s["name"] != sf.step:
                continue
            if f not in s["files"]:
                s["files"] = sorted([*s["files"], f])
                changes.append(f"step {sf.index + 1} ({sf.step}): file {f}")
            status = "done" if sf.finished else (
                s["status"] if s["status"] != "pending" else "interrupted")
            if status != s["status"]:
                changes.append(f"step {sf.index + 1} ({sf.step}): {s['status']} -> {status}")
                s["status"] = status
        if changes:
            self.data["rebuilt"] = {"at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                                    "changes": changes[:100]}
        return changes

    def first_unfinished(self) -> int | None:
        for s in self.data["steps"]:
            if s["status"] != "done":
                return int(s["index"])
        return None

    def record_run(self, seq: Sequencer | None, result: JsonObject, start: int,
                   outcome: str | None = None, extra: JsonObject | None = None) -> None:
        """Mark what this run finished, failed or left, and which files it wrote.
        `outcome` overrides the sequencer's (a daemon that stopped before the plan
        ended); `extra` goes into the run's entry (who asked for a remote collection)."""
        finished = set(seq.finished_steps) if seq is not None else set()
        if outcome is None:
            outcome = seq.outcome if seq is not None else "not started"
        files = [os.path.basename(f) for f in (result.get("recording") or {}).get("files", [])]
        for s in self.data["steps"][start:]:
            tag = f"_{s['index'] + 1:02d}-{s['name']}"
            own = [f for f in files if tag in f]
            s["files"] = sorted(set(s["files"]) | set(own))
            if s["name"] in finished:
                s["status"] = "done"
            elif seq is not None and seq.step is not None and seq.step.name == s["name"]:
                s["status"] = "failed" if outcome.startswith("fault") else "interrupted"
        self.data["runs"].append({
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "start_step": start,
            "outcome": outcome, "faults": result.get("faults", []),
            "ticks": result.get("ticks"), "lost_records": result.get("lost_records"),
            "files": files, **(extra or {})})

    def save(self, durable: bool = True) -> None:
        """Write it whole or not at all (`pamd.wire.atomic`). `durable` fsyncs it first, so a
        power cut finds it too; without, only a process crash does (what a verdict with
        a deadline can afford: the daemon saves it durably after)."""
        # Made like the recordings beside it (as `open()` makes a file: 0644 less the
        # umask), not 0600: whoever may read the step files may read what they are.
        with atomic_text(self.path, durable=durable) as fh:
            json.dump(self.data, fh, indent=2)

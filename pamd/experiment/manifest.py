"""The manifest of a collection: the plan, each step's status and files, and every
run that worked on it. `--resume` reads it to continue from the first unfinished
step. Written atomically, so a crash never leaves half a manifest.

Also what `pamd collect` and a collection started over the network
(`pamd.net.collections`) share: the collection directory's name and what each step's
recording file states (`step_records`)."""

from __future__ import annotations

import json
import os
import time
import uuid
from typing import Any

from pamd.config.loader import LoadedConfig
from pamd.errors import ConfigError, ConfigIssue
from pamd.experiment.plan import Plan
from pamd.experiment.timeline import StepLine
from pamd.version import __version__

FORMAT, VERSION = "pamd-collection", 1


def collection_name(plan: Plan, wall_s: float | None = None) -> str:
    """`<plan>-<YYYYmmdd-HHMMSS>`: a new collection's directory (local time)."""
    return f"{plan.name}-{time.strftime('%Y%m%d-%H%M%S', time.localtime(wall_s))}"


def step_records(plan: Plan, lines: list[StepLine]) -> tuple[dict[str, Any], ...]:
    """Per step, what its recording file is named after and states as `pamd.experiment`
    metadata: the plan, the step's name and index, and the load it runs under."""
    return tuple({"step": s.name, "index": i, "plan": plan.name, "load_kg": lines[i].load_kg}
                 for i, s in enumerate(plan.steps))


class Manifest:
    def __init__(self, directory: str, data: dict[str, Any]) -> None:
        self.directory = directory
        self.data = data

    @property
    def path(self) -> str:
        return os.path.join(self.directory, "manifest.json")

    @property
    def plan_name(self) -> str:
        return self.data["plan"]["name"]

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
    def load(cls, directory: str) -> Manifest:
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

    def first_unfinished(self) -> int | None:
        for s in self.data["steps"]:
            if s["status"] != "done":
                return int(s["index"])
        return None

    def record_run(self, seq: Any, result: dict[str, Any], start: int,
                   outcome: str | None = None, extra: dict[str, Any] | None = None) -> None:
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

    def save(self) -> None:
        # Made like the recordings beside it (mode 0644 less the umask), not mkstemp's
        # 0600: whoever may read the step files may read what they are.
        tmp = os.path.join(self.directory, f".manifest-{os.getpid()}-{uuid.uuid4().hex}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(self.data, fh, indent=2)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.path)

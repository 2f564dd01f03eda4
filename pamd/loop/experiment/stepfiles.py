"""What a collection's step file says of itself, whatever its manifest says: the
`pamd.experiment` metadata the recorder writes when it opens the step's file (plan,
step, index, load) and whether the step finished in it (the sequencer's
`experiment` event `step_finished`, recorded in the file's events topic).

So a manifest left stale by a crash (the main process killed after its step files
were written, before the manifest was) is rebuilt from the files
(`Manifest.reconcile`); a file that is not a step's, or cannot be read, says nothing.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from pamd.wire.errors import RecordingError
from pamd.wire.record import files as io_files


@dataclass(frozen=True)
class StepFile:
    plan: str
    step: str
    index: int
    finished: bool  # the step's `step_finished` event is in the file
    finalised: bool  # the file has its footer (else `pamd recover` it)


def read_step_file(path: str) -> StepFile | None:
    """The file's own word on its step; None if it is no step file or unreadable."""
    try:
        finalised = io_files.is_finalised(path)
        if finalised:
            meta = io_files.describe(path)["metadata"]
        else:
            sc = io_files.scan(path)
            meta = {m.name: dict(m.metadata) for m in sc.metadata}
        exp = meta.get("pamd.experiment") or {}
        if "step" not in exp or "plan" not in exp:
            return None
        index = int(exp.get("index", -1))
        finished = False
        for ch, _schema, m in io_files.iter_messages(path):
            if not ch.topic.endswith("/events"):
                continue
            try:
                ev = json.loads(m.data)
            except ValueError:
                continue
            d = ev.get("data") or {} if isinstance(ev, dict) else {}
            if (ev.get("kind") == "experiment" and d.get("what") == "step_finished"
                    and d.get("step") == exp["step"]):
                finished = True
    except (RecordingError, OSError, ValueError, TypeError, AttributeError):
        return None
    return StepFile(str(exp["plan"]), str(exp["step"]), index, finished, finalised)

"""The tutorial's commands, read from its page (docs/tutorial.md), and their shortened
copy on the virtual clock: the slow test (tests/e2e/test_tutorial.py) runs the page's
commands as written, the default run's (tests/e2e/test_walkthrough.py) the copy that
`shortened` makes of each, so neither can drift from the page."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "tutorial.md"

#: the loads the shortened collections keep of each plan (three of the seeds' five)
SHORT_LOADS_KG = (15.0, 30.0, 50.0)
#: the shortened profiles: one faster cycle each (the page's: 0.05 Hz, 2-3 cycles)
SHORT_FREQ_HZ, SHORT_CYCLES, SHORT_SETTLE_S, SHORT_EPOCHS = 0.1, 1, 1.0, 30


def page() -> str:
    return PAGE.read_text(encoding="utf-8")


def sh_blocks(text: str | None = None) -> list[str]:
    """The page's ```sh blocks, in order."""
    return re.findall(r"```sh\n(.*?)```", page() if text is None else text, re.S)


def commands(text: str | None = None) -> list[list[str]]:
    """The `pamd ...` lines of the page's sh blocks, continuations joined, comments cut."""
    out = []
    for block in sh_blocks(text):
        joined = block.replace("\\\n", " ")
        out += [shlex.split(line.split(" #", 1)[0]) for line in joined.splitlines()
                if line.startswith("pamd ")]
    return out


def short_plan(plan: Path, out: Path) -> Path:
    """`plan` (a shipped experiment plan) kept at SHORT_LOADS_KG, every profile one
    cycle at SHORT_FREQ_HZ, a settle of SHORT_SETTLE_S: the same steps, shorter."""
    doc = yaml.safe_load(plan.read_text())
    doc["settle"] = {"seconds": SHORT_SETTLE_S}
    doc["steps"] = [s for s in doc["steps"] if float(s["load_kg"]) in SHORT_LOADS_KG]
    for holder in (doc, *doc["steps"]):
        if "profile" in holder:
            holder["profile"] = {**holder["profile"], "freq_hz": SHORT_FREQ_HZ,
                                 "cycles": SHORT_CYCLES}
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def _replace(args: list[str], flag: str, value: str) -> list[str]:
    if flag in args:
        i = args.index(flag)
        return [*args[:i + 1], value, *args[i + 2:]]
    return [*args, flag, value]


def shortened(cmd: list[str], work: Path) -> list[str]:
    """The page's command `cmd` as the default run runs it, in the directory `work`
    (the repository's config/ linked in): collections of the shortened plans, fewer
    epochs, one cycle at SHORT_FREQ_HZ, no Zenoh session, the state in `work`. Nothing
    else changes: the same verbs, files, modes, models and ranges."""
    verb, args = cmd[1], list(cmd[2:])
    if verb == "collect":
        plan = Path(args[0])
        args[0] = str(short_plan(REPO / plan, work / f"short-{plan.name}"))
        args.append("--no-progress")
    elif verb == "train":
        args += ["--epochs", str(SHORT_EPOCHS), "--quiet"]
    elif verb == "run":
        args = _replace(args, "--cycles", str(SHORT_CYCLES))
        args = _replace(args, "--freq-hz", str(SHORT_FREQ_HZ))
        args += ["--no-telemetry", "--state-dir", str(work / "state")]
    return ["pamd", verb, *args]

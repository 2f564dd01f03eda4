"""The glossary's words in the code (issue 41 item 2): docs/architecture.md's "Words"
table says, per word, what pamd does *not* call it (`setpoint`, not `sp`); its
"Glossary" says home and tare are datums, never references. This test reads both and
finds those words in pamd's identifiers (a part of a snake_case or CamelCase name:
`last_sp`, `MuscleReference`), outside the names and places listed below, each with its reason.
A new use fails; a word the table adds is checked without a change here, unless it is
a word the code rightly uses in another sense (`NOT_CHECKED`, each with why).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"

#: "not" words the code rightly uses for something else, never checked
NOT_CHECKED = {
    "segment": "the tick field that numbers a plan's steps is `segment` (the table says so)",
    "output": "a driver's output channels are outputs; the limiter's result is "
              "`valve_cmd_bar` in code and record",
}

#: a word's other forms the check finds too (`KINDS`, `event_kinds`)
FORMS = {"kind": ("kinds",)}

#: names that use a checked word and stay, wherever they stand, and why
NAMES = {
    "dump": "json.dump: serialising (the library's name)",
    "safe_dump": "yaml.safe_dump: serialising (the library's name)",
}

#: deprecated old names (issue 41 item 3, `pamd.wire.declare.deprecated`): each only in
#: the file that declares it, beside its new name, until it goes; anywhere else it fails
DEPRECATED: dict[str, dict[str, str]] = {
    "NOT_REFERENCED": {"pamd/wire/declare/fields.py": "the tick flag's old name: an alias "
                                                      "of NO_LENGTH_DATUM, the same bit"},
    "referenced": {"pamd/wire/status.py": "the muscle status's old key, declared"},
    "references": {"pamd/wire/status.py": "the muscle status's old object, declared"},
    "References": {"pamd/wire/status.py": "the muscle status's old object, its type"},
    "length_referenced": {"pamd/wire/status.py": "the old object's key, declared"},
}

#: user-facing keys that say `kind` in a sense other than a model family, and why they
#: stay: (where it is declared, the key); `test_the_user_facing_kind_keys_still_work`
#: holds each where it is
KIND_KEYS = {
    "events: kind": "the recorded event's key for the event's name (`/pamd/<rig>/events`: "
                    "t_s, tick, kind, data): recordings are read for years; readers, the "
                    "exports' `kind` column and the JSON schema name it",
    "refusals: kind": "the recorded `refusals` event's key for the refusals' cause",
    "profile: kind": "the old name of a profile's `shape` (plans, the `profile` command, "
                     "`pamd cmd profile --kind`): still accepted, never with `shape`",
    "sim faults[]: kind": "the old name of a simulated fault's `failure`: still accepted",
    "nidaqmx analog_inputs[]: kind": "the old name of an NI analog input's `measurement`: "
                                     "still accepted",
    "modbus sample_clock: kind": "the old name of what a Modbus sample clock register "
                                 "`holds`: still accepted",
}

#: where a checked word may stand in another name, and why: file -> reason, per word
ALLOWED: dict[str, dict[str, str]] = {
    "kind": {  # a model family, and only that (the Glossary); a path ending in / is a tree
        "pamd/models/": "the model kinds: their declarations, registry, files and fits",
        "pamd/client/cli/train.py": "`pamd train --kind` and each kind's options",
        "pamd/client/cli/evaluate.py": "`pamd evaluate`: the models' kinds compared",
        "pamd/client/cli/model.py": "`pamd model export/import`: the kinds a .fis holds",
        "pamd/client/recording.py": "`Event.kind`: the recorded event's key for its name, "
                                    "as `pamd.open_recording` gives it (users read it)",
        "pamd/wire/record/tables.py": "the recorded event's `kind` key, as read",
        "pamd/client/export.py": "the exports' `kind` column (the recorded event's name)",
    },
    "sp": {
        "pamd/iohost/live.py": "`sp` is the live view's spec here",
        "pamd/iohost/recorder.py": "`sp` is the recording's spec here",
        "pamd/models/anfis/compiled.py": "`sp_i` is an input's span (its scale)",
        "pamd/models/fis.py": "`sp` is the inputs' spans (their scales)",
        "pamd/loop/control/adapt.py": "`_sp` is a sum of pressures (beside `_sf`, `_sl`)",
    },
    "reference": {
        "pamd/emulate/canopen_node.py": "the CANopen encoder's preset (the device's word)",
    },
}


def _not_words() -> dict[str, str]:
    """word -> what it is not said for, from the Words table (its third column) and the
    Glossary's "never" (home, tare: datums, never references)."""
    text = DOC.read_text()
    words = text.split("| word | means | not |", 1)[1].split("\n\n", 1)[0]
    found = {}
    for row in words.splitlines()[2:]:
        cells = [c.strip() for c in row.strip("|").split("|")]
        word = re.match(r"[A-Za-z0-9_]+", cells[2]) if len(cells) > 2 else None
        if word:
            found[word.group(0).lower()] = cells[0]
    for said, never in re.findall(r"pamd calls them (\w+), never (\w+)", text):
        stem = never.rstrip("s")
        for form in (stem, stem + "s", stem + "d"):
            found[form] = said
    return found


#: other libraries' names, left out before the rest: numpy's dtype code and sort
#: algorithm, zenoh's sample kind (`sample.kind == zenoh.SampleKind.PUT`)
FOREIGN = re.compile(r"\.dtype\.kind\b|\bkind=\"stable\"|\.kind == \w+\.SampleKind\.\w+")
#: what is not code: triple-quoted strings, then quoted strings and comments
DOCSTRING = re.compile(r'("""|\'\'\')[\s\S]*?\1')
LITERAL = re.compile(r'"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'|#[^\n]*')
IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


@functools.cache
def _identifiers() -> list[tuple[str, str]]:
    """(path, identifier) of every name in pamd's and its drivers' code (strings and
    comments left out: a regular expression, much cheaper than parsing every file)."""
    out = []
    for base in ("pamd", "drivers"):
        for path in sorted((ROOT / base).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            if rel == "pamd/_moved.py":  # the old module names, kept for users' scripts
                continue
            code = LITERAL.sub(" ", DOCSTRING.sub(" ", FOREIGN.sub(" ", path.read_text())))
            out += [(rel, name) for name in set(IDENTIFIER.findall(code))]
    return out


def _parts(name: str) -> set[str]:
    return {p.lower() for p in re.split(r"_+|(?<=[a-z0-9])(?=[A-Z])", name) if p}


def _found(words: set[str], identifiers: list[tuple[str, str]] | None = None
           ) -> dict[str, set[tuple[str, str]]]:
    hits: dict[str, set[tuple[str, str]]] = {w: set() for w in words}
    forms = {form: w for w in words for form in (w, *FORMS.get(w, ()))}
    for path, name in _identifiers() if identifiers is None else identifiers:
        for part in _parts(name) & set(forms):
            hits[forms[part]].add((path, name))
    return hits


def _in(path: str, place: str) -> bool:
    """Whether `path` is `place`, or lies under it (a place ending in /)."""
    return path == place or (place.endswith("/") and path.startswith(place))


def _allowed(word: str, path: str, name: str) -> bool:
    """Whether `name`, a use of `word`, may stand in `path`: a name kept wherever it
    stands (NAMES), a deprecated old name in the file that declares it (DEPRECATED), or
    a place allowed the word (ALLOWED)."""
    return (name in NAMES or path in DEPRECATED.get(name, {})
            or any(_in(path, place) for place in ALLOWED.get(word, {})))


def _wrong(identifiers: list[tuple[str, str]] | None = None) -> list[str]:
    words = _not_words()
    checked = set(words) - set(NOT_CHECKED)
    return [f"{path}: {name} ({word!r}: the glossary says {words[word]!r})"
            for word, hits in _found(checked, identifiers).items()
            for path, name in sorted(hits) if not _allowed(word, path, name)]


def test_the_glossarys_not_words_are_not_in_the_code() -> None:
    words = _not_words()
    assert {"sp", "dump", "length0", "reference", "kind"} <= set(words), words  # read
    wrong = _wrong()
    assert not wrong, "\n".join(wrong)


def test_kind_is_a_model_family_only() -> None:
    """`kind` in another sense, anywhere outside the model family's modules, fails: an
    event's name, a refusal's cause, a fault's failure, a profile's shape."""
    again = [("pamd/iohost/process.py", "event_kind"), ("pamd/iohost/intake.py", "KINDS"),
             ("pamd/sim/faults.py", "FaultKind"), ("pamd/profiles/spec.py", "kind")]
    assert len(_wrong(again)) == len(again), _wrong(again)
    assert not _wrong([("pamd/models/registry.py", "kind_of"),
                       ("pamd/models/anfis/modelfile.py", "KINDS")])


def test_the_user_facing_kind_keys_still_work() -> None:
    """Each of KIND_KEYS where it is: the record's `kind` keys declared, and each
    renamed key's old name `kind` still accepted by the schema."""
    import dataclasses

    from drivers.modbus_map import SampleClock
    from drivers.nidaq_options import AnalogInput
    from pamd.loop.experiment.plan import PlanProfile
    from pamd.sim.faults import SimFault
    from pamd.wire.declare import events
    from pamd.wire.verbs.args import ProfileArgs

    assert "kind" in events.json_schema()["required"]  # type: ignore[operator]
    assert "kind" in {k.name for k in events.EVENTS["refusals"].payload}
    olds = {(cls.__name__, f.name): f.metadata.get("old") for cls in (
        PlanProfile, ProfileArgs, SimFault, AnalogInput, SampleClock)
        for f in dataclasses.fields(cls)}
    for renamed in (("PlanProfile", "shape"), ("ProfileArgs", "shape"),
                    ("SimFault", "failure"), ("AnalogInput", "measurement"),
                    ("SampleClock", "holds")):
        assert olds[renamed] == "kind", renamed
    assert len(KIND_KEYS) == 6


def test_the_allowances_are_still_needed() -> None:
    """An allowance whose file no longer uses the word goes (the list only shrinks)."""
    hits = _found(set(ALLOWED))
    stale = [f"{word}: {path}" for word, paths in ALLOWED.items() for path in paths
             if not any(_in(p, path) and n not in NAMES for p, n in hits[word])]
    assert not stale, "\n".join(stale)


def test_the_deprecated_names_are_still_declared() -> None:
    """A deprecated name gone from its file goes from the list too."""
    names = set(_identifiers())
    gone = [f"{name}: {path}" for name, paths in DEPRECATED.items() for path in paths
            if (path, name) not in names]
    assert not gone, "\n".join(gone)


def test_the_check_sees_a_not_word() -> None:
    """The check itself: the parts of a name, snake_case and CamelCase."""
    assert "sp" in _parts("last_sp") and "sp" in _parts("SP_RATE")
    assert "reference" in _parts("MuscleReference") and "sp" not in _parts("spec")
    # an old datum name outside its declaration is found (`referenced` in the loop's code)
    assert "referenced" in _not_words() and "referenced" in _parts("length_referenced")
    assert not _allowed("referenced", "pamd/loop/control/muscle.py", "referenced")
    assert not _allowed("referenced", "pamd/loop/devices/datum_file.py", "length_referenced")
    assert _allowed("referenced", "pamd/wire/status.py", "referenced")


# -- verb: a command's name sent to the loop, never a sub-command of the CLI ------------

#: the CLI's and the emulators' modules that say "verb", each for what it does with one
#: (a module not listed says sub-command, action or its protocol's own word, never verb)
SAYS_VERB = {
    "pamd/client/cli/net.py": "`pamd cmd VERB`: sends a verb, its options from the verb's spec",
    "pamd/client/cli/reference.py": "documents `pamd cmd`'s verbs in docs/cli-reference.md",
    "pamd/client/cli/run.py": "checks `pamd run`'s options as the verbs they send are parsed",
    "pamd/client/cli/run_start.py": "the verbs `pamd run` sends from its start (--load, ...)",
    "pamd/client/cli/offline.py": "`pamd home` and `pamd tare` apply their verb offline",
}
VERB = re.compile(r"verb(?!ose)", re.IGNORECASE)  # not --verbose


def test_the_cli_and_the_emulators_say_verb_only_for_a_command_sent_to_the_loop() -> None:
    """A sub-command (`pamd status`) or an emulated protocol's command (socketcand's
    `open`) is not a verb: only the modules listed in SAYS_VERB say it, and each does."""
    paths = [*(ROOT / "pamd" / "client" / "cli").glob("*.py"),
             *(ROOT / "pamd" / "emulate").rglob("*.py")]
    says = {str(p.relative_to(ROOT)) for p in paths if VERB.search(p.read_text())}
    assert says - set(SAYS_VERB) == set(), "say sub-command, action or command"
    assert set(SAYS_VERB) - says == set(), "no longer says verb: drop it from SAYS_VERB"


def test_the_cli_help_says_verb_only_in_pamd_cmd() -> None:
    """The CLI's help as docs/cli-reference.md has it (generated from the parsers;
    tests/docs checks that it is current): "verb" in `pamd cmd`'s and its verbs'
    sections, and in the page's table only in their rows, never another sub-command's."""
    text = (ROOT / "docs" / "cli-reference.md").read_text()
    head, *sections = text.split("\n## `pamd ")
    wrong = [line for line in head.splitlines() if VERB.search(line) and "`pamd cmd" not in line]
    said_in = {s.split("`", 1)[0] for s in sections if VERB.search(s)}
    assert "cmd" in said_in, "the check reads the page's sections"  # `pamd cmd` says VERB
    wrong += sorted(f"pamd {name}" for name in said_in if name.split()[0] != "cmd")
    assert not wrong, wrong

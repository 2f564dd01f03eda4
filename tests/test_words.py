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
    "kind": "the config's and the commands' key stays `kind` (the table says so)",
}

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

#: where a checked word may stand in another name, and why: file -> reason, per word
ALLOWED: dict[str, dict[str, str]] = {
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
            code = LITERAL.sub(" ", DOCSTRING.sub(" ", path.read_text()))
            out += [(rel, name) for name in set(IDENTIFIER.findall(code))]
    return out


def _parts(name: str) -> set[str]:
    return {p.lower() for p in re.split(r"_+|(?<=[a-z0-9])(?=[A-Z])", name) if p}


def _found(words: set[str]) -> dict[str, set[tuple[str, str]]]:
    hits: dict[str, set[tuple[str, str]]] = {w: set() for w in words}
    for path, name in _identifiers():
        for word in _parts(name) & words:
            hits[word].add((path, name))
    return hits


def test_the_glossarys_not_words_are_not_in_the_code() -> None:
    words = _not_words()
    assert {"sp", "dump", "length0", "reference"} <= set(words), words  # the table is read
    checked = set(words) - set(NOT_CHECKED)
    wrong = [f"{path}: {name} ({word!r}: the glossary says {words[word]!r})"
             for word, hits in _found(checked).items() for path, name in sorted(hits)
             if not _allowed(word, path, name)]
    assert not wrong, "\n".join(wrong)


def _allowed(word: str, path: str, name: str) -> bool:
    return (name in NAMES or path in DEPRECATED.get(name, {})
            or path in ALLOWED.get(word, {}))


def test_the_allowances_are_still_needed() -> None:
    """An allowance whose file no longer uses the word goes (the list only shrinks)."""
    hits = _found(set(ALLOWED))
    stale = [f"{word}: {path}" for word, paths in ALLOWED.items() for path in paths
             if not any(p == path and n not in NAMES for p, n in hits[word])]
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

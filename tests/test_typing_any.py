"""`Any` only at true edges, each justified (issue 26 item 7), checked on the source.

`mypy --strict` (tests/test_typing.py) accepts an `Any` anywhere; this test asks each
one to say why it is one. An `Any` in pamd/ or drivers/ is justified when its line,
or the line above, carries a comment `# Any: <which edge>` (a YAML or JSON value
before its checker, an untyped third-party object, a value pickled across a process,
...). Imports of `Any` need none. The JSON and YAML aliases (`JsonObject`,
`JsonValue` in pamd/wire/declare/jsonsafe.py) are justified once where they are declared,
so a module that uses them names its edge by the alias and needs no comment.
"""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: the comment that justifies an `Any` on its line or the line below it
JUSTIFIED = re.compile(r"#.*\bAny:\s*\S")

def unjustified_any(source: str) -> list[int]:
    """Line numbers of the `Any`s in `source` (names in code, not in strings or
    comments, not in an import) whose line and the line above carry no `# Any:`."""
    uses: list[int] = []
    justified: set[int] = set()
    first_of_line: str | None = None  # the logical line's first name
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            if JUSTIFIED.search(tok.string):
                justified.add(tok.start[0])
        elif tok.type in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT):
            first_of_line = None
        elif tok.type == tokenize.NAME:
            if first_of_line is None:
                first_of_line = tok.string
            if tok.string == "Any" and first_of_line not in ("import", "from"):
                uses.append(tok.start[0])
    return [n for n in uses if n not in justified and n - 1 not in justified]


def _found() -> dict[str, list[int]]:
    found: dict[str, list[int]] = {}
    for top in ("pamd", "drivers"):
        for path in sorted((ROOT / top).rglob("*.py")):
            lines = unjustified_any(path.read_text())
            if lines:
                found[path.relative_to(ROOT).as_posix()] = lines
    return found


def test_every_any_says_which_edge_it_is() -> None:
    found = _found()
    assert not found, (
        "an `Any` without `# Any: <which edge>` on its line or the line above "
        "(type it if a real type exists: a TypedDict, a Protocol, `object` and "
        f"narrowing, JsonObject/JsonValue from pamd/wire/declare/jsonsafe.py): {found}")


def test_the_check_finds_an_unjustified_any_and_accepts_a_justified_one() -> None:
    src = (
        "from typing import Any\n"
        "import typing\n"
        "x: Any = 1\n"  # 3: unjustified
        "y: Any = 2  # Any: a YAML value, checked by the schema\n"
        "# Any: an untyped third-party object\n"
        "z: dict[str, Any] = {}\n"
        "w = typing.Any  # a comment that names no edge\n"  # 7: unjustified
        "s = 'Any'  # in a string: not a use\n"
        "# Any is mentioned in a comment\n"
        "def f(a: int,\n"
        "      b: Any) -> None: ...\n"  # 11: unjustified
        "v: Any  # Any:\n"  # 12: a marker that says nothing
        "from typing import (\n"
        "    Any,\n"  # 14: an import over lines: not a use
        ")\n")
    assert unjustified_any(src) == [3, 7, 11, 12]

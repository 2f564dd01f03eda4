"""The generated reference pages are current: each is its generator's output, so the
command line's options, the exit codes and the run summary's keys in the docs are the
code's (as tests/config/test_docs.py, tests/declare/test_fields.py and
tests/models/test_kind_declaration.py keep the config, fields and kinds pages)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from pamd.client.cli import exit_codes, reference
from pamd.client.cli.main import COMMANDS
from pamd.wire.declare import summary_keys as summary
from pamd.wire.errors import EXIT_MEANINGS

DOCS = Path(__file__).resolve().parents[2] / "docs"

PAGES: dict[str, tuple[Callable[[], str], str]] = {
    "cli-reference.md": (reference.markdown, "pamd.client.cli.reference"),
    "exit-codes.md": (exit_codes.markdown, "pamd.client.cli.exit_codes"),
    "run-summary.md": (summary.markdown, "pamd.wire.declare.summary_keys"),
}


@pytest.mark.parametrize("name", sorted(PAGES))
def test_the_generated_page_is_current(name: str) -> None:
    generate, module = PAGES[name]
    assert (DOCS / name).read_text() == generate(), (
        f"docs/{name} is stale: python -m {module} > docs/{name}")


def test_the_cli_reference_has_every_sub_command_action_and_verb() -> None:
    from pamd.wire.verbs.table import VERBS

    text = reference.markdown()
    for command in COMMANDS:
        assert f"\n## `pamd {command.name}`\n" in text, command.name
    for action in ("export", "import", "save"):
        assert f"\n## `pamd model {action}`\n" in text
    for verb in VERBS.names:
        assert f"\n## `pamd cmd {verb}`\n" in text, verb
    run = text.split("\n## `pamd run`\n", 1)[1].split("\n## ", 1)[0]
    assert "| `--duration S` |" in run and "| `--record DIR` |" in run  # the options table
    assert "usage: pamd run [-h]" in run and "examples:" in run


def test_every_exit_status_given_has_a_meaning_and_every_meaning_a_status() -> None:
    exit_codes.check()  # raises naming what is missing
    given = {r.code for r in exit_codes.raisers()}
    assert {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 130, 141} <= given
    assert set(EXIT_MEANINGS) == given
    names = {r.name for r in exit_codes.raisers()}
    assert {"pamd.wire.errors.ConfigError", "pamd.wire.zconf.NoDaemon",
            "pamd.daemon.service.riglock.RigBusy", "pamd.client.cli.main.EXIT_BROKEN_PIPE"} <= names


def test_a_status_without_a_meaning_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """The check fires when a class gives a status EXIT_MEANINGS does not explain."""
    extra = exit_codes.Raiser("pamd.x.NewError", 42, "")
    monkeypatch.setattr(exit_codes, "raisers", lambda: [*exit_codes.error_classes(), extra])
    with pytest.raises(SystemExit, match=r"add a meaning for \[42\]"):
        exit_codes.check()

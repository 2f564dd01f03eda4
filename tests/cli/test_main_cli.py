"""The CLI entry point: a reader that goes away (`pamd status | head`) ends the
sub-command quietly, library chatter stays out of the operator's terminal, and a
sub-command's module is imported only when it is chosen."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from pamd.client.cli.main import COMMANDS, EXIT_BROKEN_PIPE, build_parser, chosen_command

REPO = Path(__file__).resolve().parents[2]


def test_a_closed_pipe_ends_the_sub_command_without_a_traceback() -> None:
    # `pamd check-config ... | head -0`: the reader is gone before pamd writes
    proc = subprocess.Popen(
        [sys.executable, "-m", "pamd", "check-config", str(REPO / "config" / "sim.yaml")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=REPO)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == EXIT_BROKEN_PIPE, err
    assert "BrokenPipeError" not in err and "Traceback" not in err and "Exception" not in err



def test_emulate_is_quiet_and_stops_without_a_traceback(tmp_path: Path, socat: str) -> None:
    import signal

    import yaml

    from pamd.emulate.testing import emulated_dict, free_port, write_config

    cfg = write_config(tmp_path, emulated_dict(tmp_path, free_port(), links="pty"))
    proc = subprocess.Popen([sys.executable, "-m", "pamd", "emulate", "--config", str(cfg)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=REPO, start_new_session=True)
    assert proc.stdout is not None
    try:
        ready = yaml.safe_load(proc.stdout.readline())
        assert ready["ready"] is True
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C at a terminal: the whole group
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0 and '"stopped": true' in out
    assert "Traceback" not in err and "Exception" not in err, err
    # pymodbus's "Server listening", canopen's NMT chatter: below warning, not shown
    assert "listening" not in err and "NMT" not in err, err


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str | None]]:
    # argparse keeps the sub-commands' help lines nowhere public
    sub = next(a for a in parser._actions  # noqa: SLF001
               if isinstance(a, argparse._SubParsersAction))  # noqa: SLF001
    return [(str(a.dest), a.help) for a in sub._choices_actions]  # noqa: SLF001


def test_the_declared_subcommands_are_what_their_modules_add() -> None:
    """`pamd --help` lists the declaration (COMMANDS); each module's own parser must say
    the same name and help line, in the same order, or the listing lies."""
    declared = [(c.name, c.help) for c in COMMANDS]
    assert _subcommands(build_parser()) == declared


def _imported_by(*argv: str) -> tuple[set[str], str]:
    """The pamd modules a fresh `pamd ARGV` imported, and what it printed."""
    code = ("import sys\nfrom pamd.client.cli.main import main\ntry:\n    main(sys.argv[1:])\n"
            "except SystemExit:\n    pass\n"
            "print('MODULES', *sorted(m for m in sys.modules if m.startswith('pamd')))")
    out = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                         cwd=REPO, timeout=120, check=True).stdout
    text, _, modules = out.rpartition("MODULES")
    return set(modules.split()), text


def test_help_lists_every_subcommand_without_importing_them() -> None:
    modules, text = _imported_by("--help")
    for command in COMMANDS:
        assert f"    {command.name}" in text, command.name
    assert not {c.module for c in COMMANDS} & modules
    assert "pamd.daemon.daemon" not in modules and "pamd.loop.control.controller" not in modules


def test_a_chosen_subcommand_imports_its_module_only() -> None:
    modules, text = _imported_by("status", "--help")
    assert "--connect" in text and "pamd.client.cli.net" in modules  # status's own parser
    assert "pamd.client.cli.run" not in modules and "pamd.daemon.daemon" not in modules
    modules, text = _imported_by("-v", "run", "--help")
    assert "--profile" in text and "pamd.client.cli.run" in modules


def test_the_chosen_subcommand_is_the_first_word_not_an_option() -> None:
    assert chosen_command(["-v", "run", "--duration", "3"]) == COMMANDS[0]
    status = chosen_command(["--verbose", "status", "--json"])
    assert status is not None and status.name == "status"
    assert chosen_command(["--help"]) is None and chosen_command([]) is None
    assert chosen_command(["rnu"]) is None  # argparse then lists the choices


def test_help_suggests_the_readmes_first_command() -> None:
    """`pamd --help` starts a new user where the README does (issue 40: it suggested a
    30 s virtual-clock run, the README a 10 s real-clock one)."""
    from pamd.client.cli.main import FIRST_COMMAND

    readme = (REPO / "README.md").read_text()
    first = readme.split("## The two commands", 1)[1].split("```sh\n", 1)[1].split("\n", 1)[0]
    assert first == f"pip install . && {FIRST_COMMAND}", first
    out = subprocess.run([sys.executable, "-m", "pamd", "--help"], capture_output=True,
                         text=True, cwd=REPO, check=True).stdout
    assert FIRST_COMMAND in " ".join(out.split()), out


def test_every_exit_code_is_listed() -> None:
    """Each exit code pamd's errors and sub-commands give has its row in the exit-code table
    (docs/exit-codes.md, generated: tests/docs/test_references.py; issue 40: 5 was
    missing)."""
    import re

    codes = {0, 130}  # done; Ctrl-C outside a run (pamd.client.cli.main)
    for path in (REPO / "pamd").rglob("*.py"):
        text = path.read_text()
        codes |= {int(n) for n in re.findall(r"^\s+exit_code = (\d+)$", text, re.M)}
        codes |= {int(n) for n in re.findall(r"^EXIT_[A-Z_]+ = (\d+)$", text, re.M)}
    assert {1, 2, 3, 4, 5, 6, 7, 8, 141} <= codes, codes
    tables = (REPO / "docs" / "exit-codes.md").read_text().split("| exit code | meaning |")[1:]
    assert tables, "no exit-code table"
    rows = {int(m) for t in tables
            for m in re.findall(r"^\| (\d+) \|", t.split("\n\n", 1)[0], re.M)}
    assert codes <= rows, f"not listed: {sorted(codes - rows)}"

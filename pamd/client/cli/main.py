"""The `pamd` command: one sub-command per job. Errors that pamd raises on purpose
are printed as one clear message (no traceback) with the error's exit code.

The sub-commands are declared here by name (`COMMANDS`: name, module, one line of
help), and a sub-command's module is imported only when it is chosen: `pamd --help`
lists them all from the declaration without importing the daemon, the controller or
the models, and `pamd status` does not import the daemon either
(bench/cli_startup.py prints the cost). `build_parser()` builds every sub-command's
full parser (for tests and tools that read them all).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, cast

from pamd.wire.errors import PamdError
from pamd.wire.version import __version__


class SubCommand(Protocol):
    """A sub-command module: it adds its parser (whose `func` runs it)."""

    def add_parser(self, sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None: ...


@dataclass(frozen=True)
class SubCommandEntry:
    """One sub-command, declared without importing it: its name, the pamd.client.cli module
    whose `add_parser` adds it (one module may add several), and the line that
    `pamd --help` shows (the module's own `help=` says the same; tests/cli checks)."""

    name: str
    module: str
    help: str


def _commands(module: str, *pairs: tuple[str, str]) -> tuple[SubCommandEntry, ...]:
    return tuple(SubCommandEntry(name, f"pamd.client.cli.{module}", text) for name, text in pairs)


#: The sub-commands, in the order `pamd --help` lists them.
COMMANDS: tuple[SubCommandEntry, ...] = (
    *_commands("run", ("run", "run the rig (default: the simulated rig)")),
    *_commands("check_config", ("check-config", "validate a rig config file")),
    *_commands("collect", ("collect", "run an experiment plan (e.g. the 0.05 Hz sine sweep "
                                      "under loads)")),
    *_commands("tune", ("tune", "identify the pressure or position loop on the rig and "
                                "derive its gains")),
    *_commands("commission", ("commission", "measure a rig's signals, check their signs, "
                                            "propose thresholds")),
    *_commands("recordings",
               ("inspect", "what a recording or a collection holds (channels, counts, "
                           "metadata, faults, lost records; steps, loads, files)"),
               ("export", "a recording for MATLAB (.mat) or as named CSV tables"),
               ("recover", "turn an unfinished recording (crash, SIGKILL, power cut) into a "
                           "valid file holding every complete chunk")),
    *_commands("emulate", ("emulate", "serve an emulated rig through real protocols")),
    *_commands("train", ("train", "train an inverse model (ANFIS or another kind) or a "
                                  "forward force model from recorded runs or tables")),
    *_commands("evaluate", ("evaluate", "metrics and plots of inverse models on recorded "
                                        "data")),
    *_commands("service",
               ("safe-outputs", "write the last known-good safe outputs to the devices"),
               ("install-service", "install the systemd unit, its user and directories")),
    # offline datums on the configured rig (no daemon, no Zenoh)
    *_commands("home", ("home", "set a muscle's length datum (offline, on the configured "
                                "rig)")),
    *_commands("tare", ("tare", "zero a load cell (offline, on the configured rig)")),
    # clients of a running daemon over Zenoh (status, cmd, watch) and the lab router
    *_commands("net",
               ("status", "ask a running daemon how it is (over Zenoh)"),
               ("cmd", "command a running daemon (over Zenoh)"),
               ("token", "where a rig's command credential is; a new one with --rotate"),
               ("watch", "live table of a running daemon's muscles (over Zenoh)")),
    *_commands("router", ("router", "run a Zenoh router (for a lab with TLS and access "
                                    "control)")),
    *_commands("model", ("model", "model files: MATLAB .fis export and import; a running "
                                  "daemon's adapted model")),
    *_commands("view", ("plot", "figures of a recording: pressure, length, force, "
                                "hysteresis (PNG)")),
)


#: The first command `pamd --help` suggests: the README's first (tests/cli checks).
FIRST_COMMAND = "pamd run --duration 10 --profile sine"


def _top_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pamd",
        description="Controller daemon for pneumatic artificial muscle test beds. "
        "Runs the rig at a fixed rate under PID pressure control, safely.",
        epilog=f"Start with `{FIRST_COMMAND}` (the built-in simulated rig, 10 s on the real "
        "clock: the README's first command), then `pamd check-config YOUR.yaml` for a real "
        "rig.",
    )
    parser.add_argument("--version", action="version", version=f"pamd {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="more log output")
    return parser


def _module(name: str) -> SubCommand:
    """The sub-command module, imported now (the one lazy import of the CLI)."""
    return cast(SubCommand, importlib.import_module(name))


def _build(full: set[str]) -> argparse.ArgumentParser:
    """The parser with the full sub-parsers of the modules in `full`; every other
    sub-command only as its declared name and help line (enough for `pamd --help`
    and for argparse to list the choices of a misspelt one)."""
    parser = _top_parser()
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    added: set[str] = set()
    for command in COMMANDS:
        if command.module not in full:
            sub.add_parser(command.name, help=command.help)
        elif command.module not in added:
            _module(command.module).add_parser(sub)
            added.add(command.module)
    return parser


def build_parser() -> argparse.ArgumentParser:
    """Every sub-command's full parser (imports every sub-command's module)."""
    return _build({command.module for command in COMMANDS})


def chosen_command(argv: Sequence[str]) -> SubCommandEntry | None:
    """The sub-command `argv` names: its first word that is not an option (the
    top-level options take no value), or None (none, or not a declared name)."""
    for word in argv:
        if word == "--" or not word.startswith("-"):
            return next((c for c in COMMANDS if c.name == word), None)
    return None


def build_parser_for(argv: Sequence[str]) -> argparse.ArgumentParser:
    """The parser for this command line: the chosen sub-command's module imported and
    its parser full, the others declared only."""
    command = chosen_command(argv)
    return _build({command.module} if command else set())


#: Exit status of a command that did its job (pamd.wire.errors.EXIT_MEANINGS says what each
#: status means; docs/exit-codes.md lists them).
EXIT_OK = 0
#: Exit status of a command interrupted by Ctrl-C outside a run (a run's own Ctrl-C
#: stops it in its safe state: EXIT_OK), as a shell reports SIGINT: 128 + 2.
EXIT_INTERRUPTED = 130
#: Exit status of a sub-command whose reader went away (`pamd status | head`): 128 + SIGPIPE,
#: what a Unix tool killed by the signal reports.
EXIT_BROKEN_PIPE = 141


def _quiet_libraries(record: logging.LogRecord) -> bool:
    """pamd's own log at its level; the libraries' (pymodbus, canopen, python-can,
    zenoh, asyncio) only from warnings up, unless -v."""
    return record.name.startswith("pamd") or record.levelno >= logging.WARNING


#: Sub-commands that reload their config on SIGHUP (a daemon): the signal is held
#: from the first line of `main` until their handler is installed, so that one sent
#: during the start (imports, config, drivers) is kept and said, not the default
#: action's silent death (`pamd.client.cli.run._install_signals` takes it up).
HOLD_SIGHUP = frozenset({"run"})


def main(argv: Sequence[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else list(argv)
    command = chosen_command(words)
    if (argv is None and command is not None and command.name in HOLD_SIGHUP
            and threading.current_thread() is threading.main_thread()):
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGHUP})
    parser = build_parser_for(words)
    args = parser.parse_args(words)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="pamd: %(message)s", stream=sys.stderr)
    if not args.verbose:
        for handler in logging.getLogger().handlers:
            handler.addFilter(_quiet_libraries)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2  # as argparse exits for bad arguments (ConfigError's code)
    try:
        code = int(args.func(args) or EXIT_OK)
        sys.stdout.flush()  # a closed pipe shows here, not as a warning at exit
        return code
    except BrokenPipeError:
        # The reader of our output went away: nothing more is worth saying. Point
        # stdout at /dev/null so the interpreter's own flush at exit stays quiet.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except PamdError as exc:
        print(f"pamd: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED

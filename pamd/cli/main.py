"""The `pamd` command: one sub-command per job. Errors that pamd raises on purpose
are printed as one clear message (no traceback) with the error's exit code."""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence
from typing import Protocol

from pamd.cli import check_config, collect, emulate, evaluate, recordings, run, service, train, tune
from pamd.cli import commission as commission_cli
from pamd.cli import home as home_cli
from pamd.cli import model as model_cli
from pamd.cli import net as net_cli
from pamd.cli import router as router_cli
from pamd.cli import tare as tare_cli
from pamd.cli import view as view_cli
from pamd.errors import PamdError
from pamd.version import __version__


class SubCommand(Protocol):
    """A sub-command module: it adds its parser (whose `func` runs it)."""

    def add_parser(self, sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None: ...


#: The sub-commands, in the order `pamd --help` lists them.
COMMANDS: tuple[SubCommand, ...] = (
    run, check_config, collect, tune, commission_cli, recordings, emulate, train, evaluate, service,
    # offline references on the configured rig (no daemon, no Zenoh)
    home_cli, tare_cli,
    # clients of a running daemon over Zenoh (status, cmd, watch) and the lab router
    net_cli, router_cli, model_cli,
    view_cli,  # pamd plot (pamd.view)
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pamd",
        description="Controller daemon for pneumatic artificial muscle test beds. "
        "Runs the rig at a fixed rate under PID pressure control, safely.",
        epilog="Start with `pamd run --clock virtual --duration 30 --profile sine` (the "
        "built-in simulated rig), then `pamd check-config YOUR.yaml` for a real rig.",
    )
    parser.add_argument("--version", action="version", version=f"pamd {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in COMMANDS:
        mod.add_parser(sub)
    return parser


#: Exit status of a verb whose reader went away (`pamd status | head`): 128 + SIGPIPE,
#: what a Unix tool killed by the signal reports.
EXIT_BROKEN_PIPE = 141


def _quiet_libraries(record: logging.LogRecord) -> bool:
    """pamd's own log at its level; the libraries' (pymodbus, canopen, python-can,
    zenoh, asyncio) only from warnings up, unless -v."""
    return record.name.startswith("pamd") or record.levelno >= logging.WARNING


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="pamd: %(message)s", stream=sys.stderr)
    if not args.verbose:
        for handler in logging.getLogger().handlers:
            handler.addFilter(_quiet_libraries)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        code = int(args.func(args) or 0)
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
        return 130

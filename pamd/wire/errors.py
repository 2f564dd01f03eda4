"""The error hierarchy: every error pamd raises on purpose speaks to the operator.

Each message says what is wrong and, where there is one, what to do next. The CLI
prints the message (no traceback) and exits with the class's exit code.
"""

from __future__ import annotations


class PamdError(Exception):
    """Base of every error pamd raises on purpose."""

    exit_code = 1


class ConfigError(PamdError):
    """A configuration file (rig config, plan, calibration) is invalid.

    Holds one or more `ConfigIssue`s, each with file, line and key path.
    """

    exit_code = 2

    #: issues the message lists (all of them stay in `issues`): a file with thousands
    #: of bad entries says the first ones and how many more
    SHOWN = 20

    def __init__(self, issues: list[ConfigIssue]) -> None:
        self.issues = issues
        lines = [str(i) for i in issues[:self.SHOWN]]
        n = len(issues)
        if n > self.SHOWN:
            lines.append(f"... and {n - self.SHOWN} more")
        head = "invalid configuration" if n == 1 else f"{n} configuration errors"
        super().__init__(head + ":\n  " + "\n  ".join(lines))

    def __reduce__(self) -> tuple[type[ConfigError], tuple[list[ConfigIssue]]]:
        """Pickled with its issues (a config read in a child process comes back as it
        was raised), not with the message `Exception` would pass to `__init__`."""
        return (type(self), (self.issues,))


class ConfigIssue:
    """One problem in a config file: where, which key, what was expected, what was found."""

    def __init__(
        self, file: str, line: int | None, path: str, expected: str, found: str = ""
    ) -> None:
        self.file, self.line, self.path = file, line, path
        self.expected, self.found = expected, found

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line else self.file
        found = f", found {self.found}" if self.found else ""
        key = f" {self.path}:" if self.path else ""
        return f"{where}:{key} expected {self.expected}{found}"

    def __repr__(self) -> str:
        return f"ConfigIssue({self!s})"


class DriverError(PamdError):
    """A hardware driver cannot be found, opened, or has failed."""

    exit_code = 3


class CommandRefused(PamdError):
    """A command (CLI, profile, remote) was refused before anything moved."""

    exit_code = 4


class ModelError(PamdError):
    """A model file or training data set is unusable."""

    exit_code = 5


class RecordingError(PamdError):
    """A recording cannot be written or read."""

    exit_code = 6


class FileWriteError(PamdError, OSError):
    """A file pamd keeps (a config on --save, the datums, a model file, ...) could
    not be written; the old one is as it was (`pamd.wire.atomic`). An OSError too, so that
    whoever handled a failed write before (the service's state files) still does."""

    exit_code = 9


#: What each exit status of a `pamd` command means, declared once: the error classes
#: above (and the few elsewhere: `NoDaemon`, `RigBusy`, ...) carry their `exit_code`,
#: the command line (`pamd.client.cli.main`) its own statuses; docs/exit-codes.md is generated
#: from this table and those classes (`python -m pamd.client.cli.exit_codes`), and a test
#: fails when a status is given that has no meaning here, or the reverse.
EXIT_MEANINGS: dict[int, str] = {
    0: "done; a run stopped by SIGTERM or Ctrl-C that reached its safe state too, even "
       "with a fault latched (the fault is in the summary and in the state directory, and "
       "the next start comes back latched)",
    1: "a run ended in FAULT/ESTOP (a run with `--duration` or `--cycles` whose rig faults "
       "ends by itself, once its safe state holds); `pamd tune --plot` without matplotlib",
    2: "bad config, arguments or rig name",
    3: "driver error",
    4: "command, profile or plan refused before anything moved",
    5: "a model file or training data unusable; `pamd train`/`evaluate` without an extra "
       "they need (`--plot`: matplotlib, `pip install 'pamd[plot]'`; `--kind mlp`/`svr`: "
       "`pamd[ml]`; a `.mat` table: `pamd[mat]`)",
    6: "a recording cannot be read or written; `pamd plot` without matplotlib, "
       "`pamd export --mat` without scipy",
    7: "no daemon answers (`pamd status`, `cmd`, `watch`, `model save`)",
    8: "a port, device, channel or state directory of the run is in use by another daemon "
       "(it names which and who; nothing was opened)",
    9: "a file pamd keeps could not be written (it names the file; the old one is as it "
       "was): a full disk, a file-size limit, no permission",
    130: "interrupted by Ctrl-C outside a run",
    141: "its reader went away (`pamd status` piped into `head`, which exits first)",
}

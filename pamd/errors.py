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
    """A file pamd keeps (a config on --save, the references, a model file, ...) could
    not be written; the old one is as it was (`pamd.atomic`). An OSError too, so that
    whoever handled a failed write before (the service's state files) still does."""

    exit_code = 9

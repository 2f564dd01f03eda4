"""Progress for the command line's long work: one bar per phase, each with its total
and its ETA (reading the data, each training start, its epochs), and times said as
wall time (what the operator waited), never as one part's CPU or compute time.

tqdm is imported only when a bar is shown (`--quiet` shows none). A bar's count never
passes its total (tqdm warns "clamping frac to range [0, 1]" and shows a negative ETA
when it does): `Phase.advance_to` holds it there.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from typing import Protocol


class Bar(Protocol):
    """What is used of a tqdm progress bar (tqdm has no type information)."""

    n: float
    total: float

    def update(self, n: float = 1) -> bool | None: ...
    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None: ...
    def refresh(self) -> None: ...
    def close(self) -> None: ...


def bar(desc: str, total: float, unit: str, *, quiet: bool = False,
        unit_scale: bool = False) -> Bar | None:
    """A bar on stderr for one phase (None with `quiet`)."""
    if quiet:
        return None
    from tqdm import tqdm

    made: Bar = tqdm(total=total, desc=desc, unit=unit, unit_scale=unit_scale,
                     unit_divisor=1024 if unit == "B" else 1000, file=sys.stderr,
                     dynamic_ncols=True, leave=True)
    return made


def advance_to(b: Bar, n: float) -> None:
    """Set the bar's count to `n`, never past its total (nor back)."""
    b.n = max(b.n, min(n, b.total))
    b.refresh()


def wall_text(seconds: float) -> str:
    """A wall time as people read it: 8.4 s, 2 min 43 s, 1 h 05 min."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, s = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {s:02d} s"
    hours, m = divmod(minutes, 60)
    return f"{hours} h {m:02d} min"


class Reading:
    """The reading phase: one bar over the bytes of the files to read."""

    def __init__(self, files: Sequence[str], quiet: bool) -> None:
        sizes = {f: _size(f) for f in files}
        self.sizes = sizes
        self.bar = bar(f"reading {len(files)} file(s)", sum(sizes.values()), "B",
                       quiet=quiet, unit_scale=True)

    def file_read(self, path: str) -> None:
        if self.bar is not None:
            advance_to(self.bar, self.bar.n + self.sizes.get(path, 0))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class Training:
    """Training's phases: one bar per start (each `steps` long, counted on from the
    start before), updated once per epoch (or generation) with the errors."""

    def __init__(self, steps: int, starts: int, unit: str, error: str, quiet: bool) -> None:
        self.steps = max(1, steps)
        self.starts = max(1, starts)
        self.unit = unit
        self.error = error
        self.quiet = quiet
        self.start = -1
        self.bar: Bar | None = None

    def __call__(self, step: int, err: float, val: float | None) -> None:
        k = (step - 1) // self.steps
        if k != self.start:
            self._open(k)
        if self.bar is not None:
            advance_to(self.bar, step - k * self.steps)
            post = f"train {self.error} {err:.4g}" + (f", val {self.error} {val:.4g}"
                                                      if val is not None else "")
            self.bar.set_postfix_str(post, refresh=True)

    def _open(self, k: int) -> None:
        self.close()
        self.start = k
        n = max(self.starts, k + 1)
        desc = f"training, start {k + 1}/{n}" if n > 1 else "training"
        self.bar = bar(desc, self.steps, self.unit, quiet=self.quiet)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _size(path: str) -> int:
    try:
        return os.path.getsize(path)
    except OSError:
        return 0  # reading says what is wrong with it

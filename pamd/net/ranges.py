"""The io process's range check of a command, before the loop's mailbox: muscle names
and pressures against the limits of the latest status snapshot (refreshed once a
second; the loop checks again against the present state)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

from pamd.commands import REGISTRY
from pamd.errors import CommandRefused
from pamd.net.board import Board

LIMITS_REFRESH_S = 1.0


class PressureRanges:
    def __init__(self, muscles: tuple[str, ...], board: Callable[[], Board | None]) -> None:
        self.muscles = muscles
        self.board = board
        self._limits: dict[str, float] = {}
        self._limits_t = -1e9

    def check(self, verb: str, p: dict[str, Any]) -> None:
        """Muscle names and pressures against the limits, before the mailbox (the loop
        checks again against the present state)."""
        muscle = p.get("muscle")
        if isinstance(muscle, str) and muscle not in self.muscles:
            raise CommandRefused(f"no muscle named {muscle!r}; muscles: "
                                 f"{', '.join(self.muscles)}")
        fields = REGISTRY.pressure_fields.get(verb)
        if not fields:
            return
        limits = self._pressure_limits()
        for name in [muscle] if isinstance(muscle, str) else list(self.muscles):
            top = limits.get(name)
            for f in fields:
                v = p.get(f)
                if isinstance(v, (int, float)) and not isinstance(v, bool) and (
                        v < 0.0 or (top is not None and v > top)):
                    rng = f"0-{top:g} bar" if top is not None else "at least 0 bar"
                    raise CommandRefused(f"{name}: {f}={v:g} is outside {rng}")

    def _pressure_limits(self) -> dict[str, float]:
        now = time.monotonic()
        if now - self._limits_t >= LIMITS_REFRESH_S and (board := self.board()) is not None:
            got = board.read_status()
            if got is not None:
                self._limits_t = now
                try:
                    ms = json.loads(got[0]).get("muscles", {})
                    self._limits = {n: float(m["limits"]["max_pressure_bar"])
                                    for n, m in ms.items()}
                except (ValueError, KeyError, TypeError, AttributeError):
                    pass
        return self._limits

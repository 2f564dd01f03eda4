"""A sim driver opened on a clock that the test moves: `step(dt_s)` moves the clock by
`dt_s` and advances the driver, as the loop's virtual clock does (the driver steps its
plant to the clock's time: `pamd.drivers.sim`)."""

from __future__ import annotations

from collections.abc import Callable

from pamd.drivers.sim import SimDriver


def stepped(drv: SimDriver) -> Callable[[float], None]:
    """Open `drv` at time 0; return its `step(dt_s)`."""
    t_s = [0.0]
    drv.open(lambda: t_s[0])

    def step(dt_s: float) -> None:
        t_s[0] += dt_s
        drv.advance(dt_s)

    return step

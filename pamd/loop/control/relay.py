"""A relay-feedback test of the pressure loop (Astrom-Hagglund; Klipper's
PID_CALIBRATE), as a tick-side element of the pressure stage.

While active it stands in for the PID: the regulator setpoint is `center_bar` +
`amplitude_bar` while the measured pressure is below the switching level and
`center_bar - amplitude_bar` above it, switching when the pressure crosses the level
by more than `hysteresis_bar` (so the sensor's noise does not chatter it). The
switching level is the pressure measured while the setpoint holds `center_bar`
(its mean over the first `settle_s`, the output held at the center meanwhile), so the
oscillation is centred on where the regulator rests whatever its static gain. After
`cycles` full periods it ends by itself ("done"); a pressure that does not cross the
level within `timeout_s` of the last switch ends it too, with the reason: the
oscillation did not establish. The limiter after it still bounds every command.

Tick path: float arithmetic only, nothing allocated in `step`.
"""

from __future__ import annotations

DONE = "done"


class TickTest:
    """A test element of the tick (this relay, `pamd.loop.control.valve_pulse`'s pulse):
    inactive until started; `outcome` is "" while it runs, DONE, or why it stopped."""

    def __init__(self) -> None:
        self.active = False
        self.outcome = ""

    def begin(self) -> None:
        """Armed: the next tick runs it."""
        self.outcome = ""
        self.active = True

    def stop(self, why: str) -> None:
        """End the test (`why` becomes its outcome): what it stood in for takes over
        again this tick."""
        if self.active:
            self.active = False
            self.outcome = why


class Relay(TickTest):
    """The relay test of one muscle's pressure loop; inactive until `start`."""

    def __init__(self) -> None:
        super().__init__()
        self.center_bar = self.amplitude_bar = self.hysteresis_bar = 0.0
        self.switch_bar = 0.0  # the level it switches on (measured, see settle_s)
        self.settle_s = 0.2
        self.hold_s = 0.0
        self.timeout_s = 2.0
        self.cycles = 0
        self.switches = 0
        self.elapsed_s = 0.0  # since start
        self.relay_start_s = 0.0  # elapsed_s at the first switch of the output
        self.high = False
        self._since_switch_s = 0.0
        self._sum = 0.0
        self._n = 0

    def start(self, center_bar: float, amplitude_bar: float, hysteresis_bar: float,
              cycles: int, timeout_s: float, settle_s: float = 0.2,
              hold_s: float = 0.0) -> None:
        """Arm the test (the caller checked the bounds); the first `step` begins it."""
        self.center_bar, self.amplitude_bar = center_bar, amplitude_bar
        self.hysteresis_bar, self.cycles = hysteresis_bar, cycles
        self.timeout_s, self.settle_s, self.hold_s = timeout_s, settle_s, hold_s
        self.switches = 0
        self.elapsed_s = self._since_switch_s = self._sum = 0.0
        self.relay_start_s = 0.0
        self._n = 0
        self.switch_bar = center_bar
        self.begin()

    def step(self, pressure_bar: float, dt: float) -> float:
        """The regulator setpoint this tick."""
        self.elapsed_s += dt
        if self.elapsed_s <= self.hold_s:  # let the regulator settle at the center
            return self.center_bar
        if self.elapsed_s <= self.hold_s + self.settle_s:  # where the regulator rests
            self._sum += pressure_bar
            self._n += 1
            return self.center_bar
        if self._n > 0:  # the first relay tick: switch level known, start the relay
            self.switch_bar = self._sum / self._n
            self._n = 0
            self.high = pressure_bar < self.switch_bar
            self.relay_start_s = self.elapsed_s
            self._since_switch_s = 0.0
        self._since_switch_s += dt
        if self.high and pressure_bar > self.switch_bar + self.hysteresis_bar:
            self._switch(False)
        elif not self.high and pressure_bar < self.switch_bar - self.hysteresis_bar:
            self._switch(True)
        elif self._since_switch_s > self.timeout_s:
            self.stop(f"the oscillation did not establish: the pressure did not cross "
                      f"{self.switch_bar:.3f} bar +/- {self.hysteresis_bar:g} bar within "
                      f"{self.timeout_s:g} s of the last switch ({self.switches} switches)")
            return self.center_bar
        if self.switches >= 2 * self.cycles:
            self.stop(DONE)
            return self.center_bar
        a = self.amplitude_bar
        return self.center_bar + a if self.high else self.center_bar - a

    def _switch(self, high: bool) -> None:
        self.high = high
        self.switches += 1
        self._since_switch_s = 0.0

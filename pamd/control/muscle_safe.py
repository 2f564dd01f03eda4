"""One muscle's start-up and safe state: the methods of `MuscleController` that take
it into and out of the safe state (the rig controller calls them, in the loop's
thread, between ticks).

Start-up reads before it writes: the measured pressure becomes the setpoint
(bumpless), and a measured state outside the limits is refused with the reason. The
safe state ramps to the safe pressure at the slew limit (paced by the rig so that
every muscle arrives together), or, with the air cut (the safety chain opened, the
supply lost), closes the valves and holds the air there is. The operator's reset
trusts every signal again and closes the loop from where the muscle is.

`MuscleSafeState` is the base of `pamd.control.muscle.MuscleController`, which owns
the state these write (set up in its `__init__`; declared here and in `MuscleView`).
"""

from __future__ import annotations

import math

from pamd.control.muscle_view import MuscleView
from pamd.control.setpoint import SafeRamp
from pamd.safety.limits import LimitMonitor
from pamd.safety.load_check import LoadDisagreement, check_load
from pamd.safety.plausibility import Plausibility


class MuscleSafeState(MuscleView):
    """Start-up, the safe state, the air hold and the reset of one muscle."""

    plausibility: Plausibility
    limit_monitor: LimitMonitor
    safe_ramp: SafeRamp
    _max_pressure_bar: float
    _air_hold_bar: float  # NaN: not holding the air
    _air_out: bool

    def missing_input(self, now: float) -> str | None:
        """None when every input has a fresh reading; else which one is missing."""
        return self.inputs.missing(now)

    def load_disagreement(self) -> LoadDisagreement | None:
        """The force at rest against the declared load's weight
        (`pamd.safety.load_check`): None where they agree or the muscle declares no
        dead weight; rare path (start-up, a load change, a reload)."""
        env = self._envelope
        if not env.dead_weight:
            return None
        return check_load(self.name, self.inputs.measured_force_n(), self._load_kg,
                          env.load_tolerance_n)

    def hold_measured(self, safe_ramp: bool = False) -> None:
        """Start-up / reset: take the measured pressure as the setpoint, bumpless; with
        `safe_ramp`, ramp from there to the safe pressure at the slew limit."""
        p = max(self.inputs.measured_pressure_bar(), 0.0)
        self._setpoint_bar = p
        self._valve_cmd_bar = p
        self.pressure_loop.reset(p)
        self._profile = None
        self._safe_ramp = safe_ramp
        self.safe_ramp.unpace()
        self._started = True

    def outside_limits(self) -> str | None:
        """Start-up: why the measured state is outside the limits (None: inside). Only
        trusted readings count; an untrusted length is itself a reason."""
        env = self._envelope
        p = self.inputs.measured_pressure_bar()
        if p > env.max_pressure_bar:
            return f"pressure {p:.2f} bar above the limit {env.max_pressure_bar:g} bar"
        if not self.referenced:
            return None
        if not self.plausibility.length_ok:
            return f"length untrusted ({self.signals.length.name})"
        x = env.contraction(self.inputs.measured_length_mm())
        if x < -env.max_pretension:
            return (f"stretched {-100 * x:.1f} % (pretension limit "
                    f"{100 * env.max_pretension:.1f} %)")
        if x > env.soft_max_contraction:
            return f"contracted {100 * x:.1f} % (limit {100 * env.max_contraction:.1f} %)"
        return None

    def go_safe(self) -> None:
        """End what runs and ramp to the safe pressure (at its own slew limit until the
        rig paces it: `pace_safe_entry`)."""
        self._profile = None
        self._safe_ramp = True
        self.safe_ramp.unpace()

    def safe_entry_s(self, estop: bool) -> float:
        """How long this muscle's ramp to its safe state takes from here at its own
        slew limit (0 if never started)."""
        if not self._started:
            return 0.0
        return self.safe_ramp.time_to_target_s(self._setpoint_bar, self._safe_pressure_bar,
                                               estop)

    def pace_safe_entry(self, duration_s: float, estop: bool) -> None:
        """Ramp to the safe state in `duration_s`, the rig's common duration (never
        faster than its own slew limit)."""
        if self._started:
            self.safe_ramp.pace(self._setpoint_bar, self._safe_pressure_bar, estop,
                                duration_s)

    def hold_air(self) -> None:
        """The safety chain opened or the supply is lost (the rig controller, once the
        ESTOP or FAULT latched): the air there is is all there will be, so the valves
        close and hold it; nothing vents, not even to the safe pressure. The command
        goes (at the slew limit) to the pressure the muscle holds (`known_pressure_bar`;
        where no reading tells it, the last command, which the regulator followed,
        stays): never below it, as a regulator commanded below its pressure would vent,
        and never above it, as one commanded above would refill the muscle the moment
        the air returns (its dead time is longer than any tick that sees the air
        back). While the air is out it follows the pressure down (`follow_air`); it
        never rises until the reset."""
        if not self._started or self._air_hold_bar == self._air_hold_bar:
            return
        u = self._valve_cmd_bar
        known = self.known_pressure_bar(u)
        hold = u if known != known else known if known > 0.0 else 0.0
        self._air_hold_bar = hold if hold < self._max_pressure_bar else self._max_pressure_bar

    def follow_air(self, pressure_bar: float) -> None:
        """The tick, while the air is out and the muscle holds it, with a trusted
        `pressure_bar`: the held command comes down with the pressure the muscle holds
        (it falls as the muscle settles with the air it has, and as it leaks), never
        up. The tick passes the higher of the reading and its low-pass
        (`Plausibility.pressure_lowpass_bar`): above the pressure whether it rises or
        falls, and the running minimum of that stays within a fraction of the sensor's
        noise of the pressure, well inside a regulator's hysteresis (tens of mbar), so
        the command's descent vents nothing and ratchets nothing."""
        if pressure_bar < self._air_hold_bar:
            self._air_hold_bar = pressure_bar if pressure_bar > 0.0 else 0.0

    def known_pressure_bar(self, command_bar: float) -> float:
        """The muscle's pressure where its reading can be believed, whatever the pressure
        sensor's trust state (the air hold's; not the tick path), else NaN. A trusted
        reading: the higher of it and its low-pass (as `follow_air` takes it). An
        untrusted one (the tracking check distrusts a true reading when the air does
        not follow) is believed where the force map at the trusted force and length
        (`Plausibility.pressure_for_force`) puts the pressure nearer the reading than
        `command_bar`, or the reading follows the command within the tracking band. The
        map only tells which: its own pressure is off by the muscle's friction (a few
        tenths of a bar), too far to command a regulator at."""
        inp = self.inputs
        p = inp.pressure_bar
        if inp.pressure_ok:
            lp = self.plausibility.pressure_lowpass_bar
            return lp if lp > p else p  # above it whether it rises or falls (follow_air)
        if not (inp.pressure_fresh and p == p):
            return math.nan
        if abs(p - command_bar) <= self.limit_monitor.track_band:
            return p
        p_f = (self.plausibility.pressure_for_force(inp.force_n, inp.length_mm)
               if inp.length_ok else math.nan)
        return p if abs(p_f - p) <= abs(p_f - command_bar) else math.nan

    def set_air_out(self, out: bool) -> None:
        """The supply is out (`out`) or back. While out the pressure loop's integral
        holds (and the tracking check with it: air that is not there cannot follow a
        command). When the air returns to a muscle still holding its air, the hold comes
        down to the pressure the muscle holds (`known_pressure_bar`: also a reading the
        tracking check distrusted, where the force and length believe it), so that the
        returning air moves nothing before the operator's reset (a leak while the air
        was cut is not refilled). A reading that cannot be believed leaves the hold at
        the last pressure trusted while the air was out: the returning air then refills
        only what leaked since."""
        if out == self._air_out:
            return
        self._air_out = out
        self.pressure_loop.hold_integral = out
        hold = self._air_hold_bar
        if out or hold != hold:
            return
        p = self.known_pressure_bar(hold)
        if p < hold:
            self._air_hold_bar = p if p > 0.0 else 0.0

    @property
    def holding_air(self) -> bool:
        """The valves hold the air after the chain opened or the supply was lost."""
        return self._air_hold_bar == self._air_hold_bar

    def clear_findings(self) -> None:
        """Trust every signal again; the checks start afresh."""
        self.plausibility.clear()
        self.limit_monitor.stop_tracking()
        self.limit_monitor.reset_guards()

    def reset(self) -> None:
        """The operator's reset of a latched fault: every signal trusted again; a
        started muscle closes its loop again from where it is, one never started holds
        its measured pressure."""
        self.clear_findings()
        self._air_hold_bar = math.nan
        if self._started:
            self.pressure_loop.reset(self.inputs.pressure_bar)
            self._safe_ramp = False
        else:
            self.hold_measured()

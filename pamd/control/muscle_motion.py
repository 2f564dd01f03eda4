"""One muscle's motion commands: its references (home, tare), its mode (pressure or a
length mode), its profiles, and its inverse model and that model's adaptation. The
commands call them in the loop's thread, between ticks; each takes effect bumpless
at the next tick.

`MuscleMotion` is a base of `pamd.control.muscle.MuscleController`, which owns the
state these write (set up in its `__init__`; declared in `MuscleView`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pamd.control.muscle_view import MuscleView
from pamd.declare.jsonsafe import JsonObject
from pamd.profiles import Profile
from pamd.tick import Mode

if TYPE_CHECKING:
    from pamd.control.feedforward import Feedforward


class MuscleMotion(MuscleView):
    """References, modes, profiles and the model of one muscle."""

    def home(self, length_mm: float, raw_length_mm: float, at: str) -> float:
        """Reference the length (`Inputs.home`; the caller has run
        `pamd.safety.datums.check_home`). Returns the offset."""
        return self.inputs.home(length_mm, raw_length_mm, at)

    def tare(self, force_offset_n: float, at: str) -> None:
        """The force reference (checked by `pamd.safety.datums.tare_offset`)."""
        self.inputs.tare(force_offset_n, at)

    # -- motion (loop thread) ------------------------------------------------------------
    def start_profile(self, profile: Profile) -> None:
        """A pressure profile (or a setpoint's ramp) from the present setpoint."""
        self._profile = profile
        self._safe_ramp = False
        self.pressure_loop.reset(self.inputs.pressure_bar, self.pressure_loop.pid.i)

    def stop_profile(self) -> None:
        self._profile = None

    def resume(self, paused_s: float) -> bool:
        """After a HOLD of `paused_s`: the profile goes on where it was. Whether one runs."""
        if self._profile is None:
            return False
        self._profile.t0_s += paused_s
        return True

    def enter_mode(self, mode: Mode, use_ff: bool, ilc: bool) -> None:
        """A length mode, bumpless (`LengthControl.enter`); any profile ends, and a
        completed ramp to the safe pressure hands over to it, as a setpoint would."""
        self._profile = None
        self._safe_ramp = False
        inp = self.inputs
        self.length_control.enter(mode, use_ff, ilc, from_pressure=self._mode == Mode.PRESSURE,
                                  length_mm=inp.length_mm, force_n=inp.force_n,
                                  setpoint_bar=self._setpoint_bar)
        self._mode = mode

    def leave_length_mode(self) -> None:
        """Back to pressure mode; the setpoint stays where it is (bumpless)."""
        self._mode = Mode.PRESSURE
        self._profile = None
        self.length_control.leave()

    def set_length_targets(self, profile: Profile | None, force_n: float | None) -> None:
        """A length setpoint: its ramp (a length profile) and/or a force target."""
        if profile is not None:
            self._profile = profile
        if force_n is not None:
            self.length_control.set_force_target(force_n)

    def start_length_profile(self, profile: Profile) -> None:
        self._profile = profile
        lc = self.length_control
        if lc.ilc_on and profile.period_s > 0:
            lc.start_ilc(profile.period_s)

    def swap_model(self, feedforward: Feedforward) -> float:
        """A new inverse model; returns the pressure the outer loop takes up (bar)."""
        inp = self.inputs
        taken_up = self.length_control.swap(feedforward, inp.length_mm, inp.force_n)
        self.adaptation.bind(feedforward)
        return taken_up

    def adapt(self, action: str) -> JsonObject:
        """The `adapt` command: on, off, reset, restore or status (`Adaptation.command`)."""
        return self.adaptation.command(action)

    def adapted_parameters(self) -> JsonObject:
        """A copy of the adapted consequents and their provenance (`Adaptation.snapshot`)."""
        return self.adaptation.snapshot()

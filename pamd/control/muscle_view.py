"""What others read of one muscle: its state's read-only properties and the tick record.

`MuscleView` is the base of `pamd.control.muscle.MuscleController`, which alone writes
the state these read (its command methods and its tick). Commands, the rig controller,
the safety rules and the summary read a muscle only through these properties;
`_record` writes the muscle's slots of the tick record (plain float stores into the
preallocated record, on the tick path).
"""

from __future__ import annotations

from array import array

from pamd.calibration import MuscleReference
from pamd.control.actuation import Actuation
from pamd.control.adapt import Adaptation
from pamd.control.inputs import Inputs
from pamd.control.length_control import LengthControl
from pamd.control.pressure_loop import PressureLoop
from pamd.declare.jsonsafe import JsonObject
from pamd.profiles import Profile
from pamd.rig import MuscleSignals
from pamd.safety.envelope import MuscleEnvelope
from pamd.tick import (
    M_ADAPT_DRIFT,
    M_ADAPT_STATE,
    M_CONTRACTION,
    M_FEEDFORWARD,
    M_FLAGS,
    M_FORCE,
    M_LENGTH,
    M_MODE,
    M_PID_D,
    M_PID_I,
    M_PID_P,
    M_PRESSURE,
    M_SAFE_PRESSURE,
    M_SETPOINT,
    M_TARGET_FORCE,
    M_TARGET_LENGTH,
    M_VALVE,
    M_VELOCITY,
    Mode,
)

NAN = float("nan")


class MuscleView:
    """The read side of a muscle's state (see the module docstring); the attributes
    are set by `MuscleController.__init__`."""

    name: str
    signals: MuscleSignals
    inputs: Inputs
    length_control: LengthControl
    adaptation: Adaptation
    pressure_loop: PressureLoop
    actuation: Actuation
    finding: str | None
    limit_report: str | None
    _base: int
    _envelope: MuscleEnvelope
    onoff: bool  # on/off valves (actuation: onoff)
    _setpoint_bar: float
    _valve_cmd_bar: float
    _safe_pressure_bar: float
    _load_kg: float
    _mode: Mode
    _profile: Profile | None
    _started: bool
    _safe_ramp: bool

    @property
    def envelope(self) -> MuscleEnvelope:
        return self._envelope

    @property
    def reference(self) -> MuscleReference:
        """The length and force references (home, tare), saved in the calibration."""
        return self.signals.reference

    @property
    def referenced(self) -> bool:
        return self.signals.reference.length_referenced

    @property
    def pressure_bar(self) -> float:
        return self.inputs.pressure_bar

    @property
    def force_n(self) -> float:
        return self.inputs.force_n

    @property
    def length_mm(self) -> float:
        return self.inputs.length_mm

    @property
    def contraction(self) -> float:
        return self.inputs.contraction

    @property
    def velocity_mm_s(self) -> float:
        return self.inputs.velocity_mm_s

    @property
    def setpoint_bar(self) -> float:
        return self._setpoint_bar

    @property
    def valve_cmd_bar(self) -> float:
        return self._valve_cmd_bar

    @property
    def feedforward_bar(self) -> float:
        return self.length_control.feedforward_bar

    @property
    def target_length_mm(self) -> float:
        return self.length_control.target_length_mm

    @property
    def target_force_n(self) -> float:
        return self.length_control.target_force_n

    @property
    def safe_pressure_bar(self) -> float:
        return self._safe_pressure_bar

    @property
    def load_kg(self) -> float:
        return self._load_kg

    @property
    def mode(self) -> Mode:
        return self._mode

    @property
    def profile(self) -> Profile | None:
        return self._profile

    @property
    def started(self) -> bool:
        return self._started

    @property
    def exhaust_open(self) -> bool:
        return self.actuation.exhaust_open

    @property
    def in_length_mode(self) -> bool:
        return self.length_control.active

    @property
    def has_model(self) -> bool:
        return self.length_control.ff is not None

    @property
    def in_safe_ramp(self) -> bool:
        """Ramping to the safe pressure outside FAULT/ESTOP (a stop, a deadman, a
        start-up outside the limits)."""
        return self._safe_ramp

    def take_finding(self) -> str | None:
        finding, self.finding = self.finding, None
        return finding

    @property
    def adapt_report(self) -> JsonObject | None:
        """A freeze or a bound of the model's adaptation, not yet reported."""
        return self.adaptation.report

    def take_adapt_report(self) -> JsonObject | None:
        return self.adaptation.take_report()

    @property
    def feedforward_pending(self) -> bool:
        """The model's inputs left its training domain, or its feedforward began to
        oscillate, and that is not yet said (`pamd.control.off_data`)."""
        wd = self.length_control.watch
        return wd.pending_off or wd.pending_osc

    def feedforward_report(self) -> JsonObject:
        """The feedforward's watch for the run summary and the status: the policy and
        the shares of the running ticks off the training domain, faded, oscillating."""
        out: JsonObject = dict(self.length_control.watch.summary())
        return out

    def take_limit_report(self) -> str | None:
        report, self.limit_report = self.limit_report, None
        return report

    def take_calibration_dirty(self) -> bool:
        """Whether the device took a homed reference since the last call (then the
        calibration is to be saved, outside the loop's thread)."""
        return self.inputs.take_calibration_dirty()

    def _record(self, rec: array[float], flags: int) -> None:
        b = self._base
        inp, lc, pid = self.inputs, self.length_control, self.pressure_loop.pid
        rec[b + M_PRESSURE] = inp.pressure_bar
        rec[b + M_FORCE] = inp.force_n
        rec[b + M_LENGTH] = inp.length_mm
        rec[b + M_CONTRACTION] = inp.contraction
        rec[b + M_VELOCITY] = inp.velocity_mm_s
        # on/off valves in mode position move on the length alone (seed 004's sliding
        # mode, pamd.control.onoff): no pressure setpoint there, and none recorded
        rec[b + M_SETPOINT] = (NAN if self.onoff and lc.active and lc.position
                               else self._setpoint_bar)
        rec[b + M_FEEDFORWARD] = lc.feedforward_bar
        rec[b + M_PID_P] = pid.p
        rec[b + M_PID_I] = pid.i
        rec[b + M_PID_D] = pid.d
        rec[b + M_VALVE] = self._valve_cmd_bar
        rec[b + M_TARGET_LENGTH] = lc.target_length_mm
        rec[b + M_TARGET_FORCE] = lc.target_force_n
        rec[b + M_SAFE_PRESSURE] = self._safe_pressure_bar
        rec[b + M_MODE] = self._mode
        rec[b + M_FLAGS] = flags
        ad = self.adaptation
        rec[b + M_ADAPT_DRIFT] = ad.drift_bar
        rec[b + M_ADAPT_STATE] = ad.state

"""One muscle: the owner of its state, its commands, and its tick as a pipeline of
stages run in three phases, as ros2_control runs a controller (the rig runs each
phase for every muscle before the next: `pamd.loop.control.controller.RigController.tick`):

read      inputs     its signals, their age and plausibility (`pamd.loop.control.inputs`)
          limits     the hard limits and whether the pressure follows the command
                     written last: faults (`pamd.loop.safety.limits.LimitMonitor`)
update    setpoint   the source chosen for the rig's state and the muscle's mode: the
                     safe ramp, the air hold, a pressure profile, holding, length
                     control, or the valves positioning the length
                     (`pamd.loop.control.setpoint`, `pamd.loop.control.length_control`)
          pressure   the PID pressure loop + rate feedforward (`pamd.loop.control.pressure_loop`)
          -- the rig decides its safe state once, on every muscle's findings --
write     guards     the soft limits' bounds on the command (`pamd.loop.safety.limits.Guards`)
          limiter    the supervisor's invariants, last (`pamd.loop.safety.limiter`); a tick in
                     which the rig found a fault, or this muscle lost its pressure, is
                     already held to them (the safe state's entry)
          actuation  the command to the valves (`pamd.loop.control.actuation`)
          adapt      the model's online adaptation (`pamd.loop.control.adapt`); the tick record

Every stage is `update(t, now, dt)` on the muscle's `MuscleTick` (`tick_values`, the
values the stages hand each other: `pamd.wire.tick`). The setpoint source is chosen when
the rig's state or the muscle's mode, profile, safe ramp or air hold changes
(`_choose_source`), never branched on per tick; so is what the actuation does beyond
following the command (`Actuation.closes_pressure_loop`, `positions_length`).

No guard writes the setpoint: guards and the limiter bound the valve command only,
so the setpoint stays what the profile asked for (the summary measures tracking
against it) and nothing ratchets.

What is fixed about the muscle (limits, nominal length, force model, rate limits)
is its `MuscleEnvelope`. What changes is its state, which only this class writes:
commands and the rig controller call its methods (`home`, `enter_mode`,
`start_profile`, `go_safe`, `hold_air`, `apply_settings`, ...) and read its
properties. Start-up reads before it writes: the measured pressure becomes the
setpoint (bumpless), and a measured state outside the limits is refused with the
reason. The safe state ramps to the safe pressure at the slew limit (paced by the rig
so that every muscle arrives together), or, with the air cut (the safety chain
opened, the supply lost), closes the valves and holds the air there is. The
operator's reset trusts every signal again and closes the loop from where the muscle
is.

The tick path is plain float arithmetic on cached attributes, no I/O, no
allocation on the normal path (only a fault builds its message string).
"""

from __future__ import annotations

import math
from array import array
from dataclasses import replace
from typing import TYPE_CHECKING

from pamd.config.control_schema import PidConfig
from pamd.config.loader import LoadedConfig
from pamd.loop.control.actuation import Actuation, actuation_for
from pamd.loop.control.adapt import Adaptation
from pamd.loop.control.inputs import Inputs
from pamd.loop.control.length_control import LengthControl
from pamd.loop.control.pressure_loop import PressureLoop
from pamd.loop.control.setpoint import (
    VENT_BELOW_BAR,
    AirHold,
    Hold,
    ProfileFollower,
    SafeRamp,
    ValvesPosition,
)
from pamd.loop.control.settings import MuscleSettings
from pamd.loop.devices.bindings import MuscleSignals
from pamd.loop.devices.datum_file import MuscleDatums
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.loop.safety.limiter import Limiter
from pamd.loop.safety.limits import F_AT_LIMIT, Guards, LimitMonitor
from pamd.loop.safety.load_check import LoadDisagreement, check_load
from pamd.loop.safety.plausibility import Plausibility
from pamd.profiles import Profile
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import (
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
    M_VALVE_CMD,
    M_VELOCITY,
    Mode,
    MuscleTick,
    Stage,
    State,
)

if TYPE_CHECKING:
    from pamd.loop.control.feedforward import Feedforward, LoadedModel

S_LOAD, S_RUNNING = int(State.LOAD_CHANGE), int(State.RUNNING)
S_FAULT, S_ESTOP = int(State.FAULT), int(State.ESTOP)
NAN = math.nan
__all__ = ["VENT_BELOW_BAR", "MuscleController"]


class MuscleController:
    """State, commands and tick of one muscle (see the module docstring)."""

    # slots: attribute reads on the tick path stay specialised past CPython's 30-key
    # shared dict (issue 42 item 3)
    __slots__ = (
        'index', 'name', 'signals', '_base', 'plausibility', 'tick_values', 'inputs',
        'limit_monitor', 'safe_ramp', 'air', 'profile_follower', 'hold',
        'length_control', 'valves_position', 'ff_watch', 'actuation', 'onoff',
        'pressure_loop', 'guards', 'limiter', 'adaptation', 'length_absolute', '_mode',
        '_started', '_valve_cmd_bar', 'profile', '_safe_ramp', '_source', '_chosen_for',
        '_pid', 'limit_report', '_load_kg', '_safe_pressure_bar', '_envelope',
        '_max_pressure_bar', '_slew_limit_bar_per_s'
    )

    def __init__(self, index: int, envelope: MuscleEnvelope, cfg: LoadedConfig,
                 signals: MuscleSignals, record_base: int,
                 model: LoadedModel | None = None) -> None:
        self.index = index
        self.name = envelope.name
        self.signals = signals
        self._base = record_base
        ctl, saf, mcfg = cfg.control_of(self.name), cfg.rig.safety, cfg.muscle(self.name)
        p, f, ln = signals.pressure, signals.force, signals.length
        self.plausibility = Plausibility(self.name, (p.name, f.name, ln.name),
                                         saf.plausibility, envelope.nominal_length_mm,
                                         envelope.force_model)
        self.tick_values = MuscleTick()  # what the stages hand each other, this tick
        # The stages, in tick order (the setpoint sources: one chosen at a time).
        self.inputs = Inputs(signals, self.plausibility, envelope.nominal_length_mm)
        self.limit_monitor = LimitMonitor(envelope, p.name, saf, self.plausibility)
        self.safe_ramp = SafeRamp(envelope)
        self.air = AirHold(self.plausibility)  # the air cut (safety chain, supply): held
        self.profile_follower = ProfileFollower(envelope)
        self.hold = Hold()
        self.length_control = LengthControl(envelope, ctl.position,  # model: its model_file
                                            None if model is None else model.feedforward(),
                                            ctl.rate_feedforward_s,
                                            1.0 / cfg.rig.loop.rate_hz, ctl.feedforward)
        self.valves_position = ValvesPosition(self.length_control)
        # the watch on the model's training domain and oscillation (its reports)
        self.ff_watch = self.length_control.watch
        self.actuation: Actuation = actuation_for(signals, mcfg)
        self.onoff = mcfg.actuation == "onoff"  # on/off valves (status, tools)
        self.pressure_loop = PressureLoop(*self._pressure_gains(ctl.pid, ctl.rate_feedforward_s))
        self.guards = Guards(envelope)
        self.limiter = Limiter(envelope.max_pressure_bar)
        self.adaptation = Adaptation(self.name, mcfg.adapt,  # the model's online
                                     self.length_control.ff,  # adaptation (adapt.py)
                                     onoff=self.onoff, inputs=self.inputs,
                                     length_control=self.length_control)
        self.length_absolute = bool(
            ln.driver.is_absolute(ln.index) or mcfg.signals.length.absolute)
        # Run-time state (read through the properties below).
        self._mode = Mode.PRESSURE
        self._started = False  # True once the pressure has been read and held
        self._valve_cmd_bar = NAN  # the command written last
        # the running profile: read by others every tick (the rig's end of a profile,
        # the summary's cycles), so a plain attribute, not a property; only this class
        # writes it
        self.profile: Profile | None = None
        self._safe_ramp = False
        self._source: Stage = self.hold  # the setpoint source (`_choose_source`) ...
        self._chosen_for = -1  # ... chosen for this state (-1: to be chosen again)
        self._pid = self.pressure_loop.pid  # its terms for the record
        self.limit_report: str | None = None  # a profile held at a soft limit (> 1 s)
        self._set_envelope(envelope)
        self._load_kg = 0.0
        self._safe_pressure_bar = 0.0
        self.set_load(mcfg.load_kg)

    # -- set-up and settings (not the tick path) ----------------------------------------
    def _set_envelope(self, env: MuscleEnvelope) -> None:
        self._envelope = env
        self._max_pressure_bar = env.max_pressure_bar
        self._slew_limit_bar_per_s = env.slew_limit_bar_per_s
        self.limit_monitor.set_envelope(env)
        self.guards.set_envelope(env)
        self.limiter.max_pressure_bar = env.max_pressure_bar
        self.safe_ramp.set_envelope(env)
        self.profile_follower.set_envelope(env)
        self.length_control.set_envelope(env)
        self.inputs.set_nominal_length(env.nominal_length_mm)
        self.plausibility.set_stops(env.max_contraction, env.max_pretension)
        self._chosen_for = -1  # the sources' slews

    def _pressure_gains(self, pid: PidConfig, rate_feedforward_s: float
                        ) -> tuple[PidConfig, float]:
        """The PID's gains: valves that close their pressure loop themselves
        (`Actuation.closes_pressure_loop`: on/off valves' PWM) leave the PID nothing to
        add, so there the command is the setpoint."""
        if self.actuation.closes_pressure_loop:
            return replace(pid, kp=0.0, ki_per_s=0.0, kd_s=0.0), 0.0
        return pid, rate_feedforward_s

    def set_load(self, load_kg: float) -> None:
        """A new hanging load: a new safe pressure."""
        self._load_kg = load_kg
        self._safe_pressure_bar = self.safe_ramp.safe_pressure_bar = (
            self._envelope.safe_pressure_bar(load_kg))
        self.plausibility.set_load(load_kg)
        self.length_control.set_load(load_kg)

    def apply_settings(self, s: MuscleSettings, with_limits: bool) -> None:
        """A reloaded config (SIGHUP), applied in the loop's thread at a tick boundary.
        Gains and timeouts always; limits, slew, nominal length and a changed load (so
        the safe pressure) only `with_limits` (the rig is IDLE). The PID keeps its
        state, the integral clamped to the new limit: no bump."""
        self.pressure_loop.set_gains(*self._pressure_gains(s.pid, s.rate_feedforward_s))
        self.inputs.set_timeouts(s.pressure_timeout_s, s.force_timeout_s, s.length_timeout_s)
        self.limit_monitor.set_times(s.safety)
        self.plausibility.configure(s.safety.plausibility)
        if not with_limits:
            return
        self._set_envelope(self._envelope.with_settings(
            s.limits, s.safety, s.slew_limit_bar_per_s, s.nominal_length_mm))
        self.set_load(self._load_kg if s.load_kg is None else s.load_kg)

    # -- what others read ------------------------------------------------------------------
    @property
    def envelope(self) -> MuscleEnvelope:
        return self._envelope

    @property
    def datums(self) -> MuscleDatums:
        """The length and force datums (home, tare), saved in the calibration."""
        return self.signals.datums

    @property
    def has_length_datum(self) -> bool:
        """Whether the length has its datum: homed, or an absolute sensor's own."""
        return self.signals.datums.has_length_datum

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
        return self.tick_values.setpoint_bar

    @property
    def valve_cmd_bar(self) -> float:
        """The command written last."""
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

    @property
    def holding_air(self) -> bool:
        """The valves hold the air after the chain opened or the supply was lost."""
        return self.air.holding

    @property
    def finding(self) -> str | None:
        """A reading no longer trusted this tick, not yet reported."""
        return self.tick_values.finding

    def take_finding(self) -> str | None:
        t = self.tick_values
        finding, t.finding = t.finding, None
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
        oscillate, and that is not yet said (`pamd.loop.control.off_data`)."""
        wd = self.ff_watch
        return wd.pending_off or wd.pending_osc

    def feedforward_report(self) -> JsonObject:
        """The feedforward's watch for the run summary and the status: the policy and
        the shares of the running ticks off the training domain, faded, oscillating."""
        out: JsonObject = dict(self.ff_watch.summary())
        return out

    def take_limit_report(self) -> str | None:
        report, self.limit_report = self.limit_report, None
        return report

    def take_calibration_dirty(self) -> bool:
        """Whether the device took a homed preset since the last call (then the
        calibration is to be saved, outside the loop's thread)."""
        return self.inputs.take_calibration_dirty()

    # -- datums, modes, profiles, the model (commands: the loop's thread, between
    # ticks; each takes effect bumpless at the next tick) ---------------------------------
    def home(self, length_mm: float, raw_length_mm: float, at: str) -> float:
        """Set the length's datum (`Inputs.home`; the caller has run
        `pamd.loop.safety.datums.check_home`). Returns the offset."""
        return self.inputs.home(length_mm, raw_length_mm, at)

    def tare(self, force_offset_n: float, at: str) -> None:
        """Set the force's zero (checked by `pamd.loop.safety.datums.tare_offset`)."""
        self.inputs.tare(force_offset_n, at)

    def start_profile(self, profile: Profile) -> None:
        """A pressure profile (or a setpoint's ramp) from the present setpoint."""
        self.profile = profile
        self._safe_ramp = False
        self.pressure_loop.reset(self.inputs.pressure_bar, self.pressure_loop.pid.i)
        self._chosen_for = -1

    def stop_profile(self) -> None:
        self.profile = None
        self._chosen_for = -1

    def resume(self, paused_s: float) -> bool:
        """After a HOLD of `paused_s`: the profile goes on where it was. Whether one runs."""
        if self.profile is None:
            return False
        self.profile.t0_s += paused_s
        return True

    def enter_mode(self, mode: Mode, use_ff: bool, ilc: bool) -> None:
        """A length mode, bumpless (`LengthControl.enter`); any profile ends, and a
        completed ramp to the safe pressure hands over to it, as a setpoint would."""
        self.profile = None
        self._safe_ramp = False
        inp = self.inputs
        self.length_control.enter(mode, use_ff, ilc, from_pressure=self._mode == Mode.PRESSURE,
                                  length_mm=inp.length_mm, force_n=inp.force_n,
                                  setpoint_bar=self.tick_values.setpoint_bar)
        self._mode = mode
        self._chosen_for = -1

    def leave_length_mode(self) -> None:
        """Back to pressure mode; the setpoint stays where it is (bumpless)."""
        self._mode = Mode.PRESSURE
        self.profile = None
        self.length_control.leave()
        self._chosen_for = -1

    def set_length_targets(self, profile: Profile | None, force_n: float | None) -> None:
        """A length setpoint: its ramp (a length profile) and/or a force target."""
        if profile is not None:
            self.profile = profile
            self._chosen_for = -1
        if force_n is not None:
            self.length_control.set_force_target(force_n)

    def start_length_profile(self, profile: Profile) -> None:
        self.profile = profile
        self._chosen_for = -1
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

    # -- start-up, the safe state, the air hold, the reset (the rig controller, in the
    # loop's thread, between ticks) -----------------------------------------------------
    def missing_input(self, now: float) -> str | None:
        """None when every input has a fresh reading; else which one is missing."""
        return self.inputs.missing(now)

    def load_disagreement(self) -> LoadDisagreement | None:
        """The force at rest against the declared load's weight
        (`pamd.loop.safety.load_check`): None where they agree or the muscle declares no
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
        self.tick_values.setpoint_bar = p
        self._valve_cmd_bar = p
        self.pressure_loop.reset(p)
        self.profile = None
        self._safe_ramp = safe_ramp
        self.safe_ramp.unpace()
        self._started = True
        self._chosen_for = -1

    def outside_limits(self) -> str | None:
        """Start-up: why the measured state is outside the limits (None: inside). Only
        trusted readings count; an untrusted length is itself a reason."""
        env = self._envelope
        p = self.inputs.measured_pressure_bar()
        if p > env.max_pressure_bar:
            return f"pressure {p:.2f} bar above the limit {env.max_pressure_bar:g} bar"
        if not self.has_length_datum:
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
        self.profile = None
        self._safe_ramp = True
        self.safe_ramp.unpace()
        self._chosen_for = -1

    def safe_entry_s(self, estop: bool) -> float:
        """How long this muscle's ramp to its safe state takes from here at its own
        slew limit (0 if never started)."""
        if not self._started:
            return 0.0
        return self.safe_ramp.time_to_target_s(self.tick_values.setpoint_bar,
                                               self._safe_pressure_bar, estop)

    def pace_safe_entry(self, duration_s: float, estop: bool) -> None:
        """Ramp to the safe state in `duration_s`, the rig's common duration (never
        faster than its own slew limit)."""
        if self._started:
            self.safe_ramp.pace(self.tick_values.setpoint_bar, self._safe_pressure_bar,
                                estop, duration_s)

    def hold_air(self) -> None:
        """The safety chain opened or the supply is lost (the rig controller, once the
        ESTOP or FAULT latched): the air there is is all there will be, so the valves
        close and hold it; nothing vents, not even to the safe pressure. The command
        goes (at the slew limit) to the pressure the muscle holds (`known_pressure_bar`;
        where no reading tells it, the last command, which the regulator followed,
        stays): never below it, as a regulator commanded below its pressure would vent,
        and never above it, as one commanded above would refill the muscle the moment
        the air returns (its dead time is longer than any tick that sees the air
        back). While the air is out it follows the pressure down (`AirHold.follow`); it
        never rises until the reset."""
        air = self.air
        if not self._started or air.holding:
            return
        u = self._valve_cmd_bar
        known = self.known_pressure_bar(u)
        hold = u if known != known else known if known > 0.0 else 0.0
        air.hold_bar = hold if hold < self._max_pressure_bar else self._max_pressure_bar
        self._chosen_for = -1

    def follow_air(self, pressure_bar: float) -> None:
        """While the air is out and the muscle holds it, with a trusted `pressure_bar`:
        the held command comes down with the pressure the muscle holds (it falls as the
        muscle settles with the air it has, and as it leaks), never up. The tick
        passes the higher of the reading and its low-pass
        (`Plausibility.pressure_lowpass_bar`): above the pressure whether it rises or
        falls, and the running minimum of that stays within a fraction of the sensor's
        noise of the pressure, well inside a regulator's hysteresis (tens of mbar), so
        the command's descent vents nothing and ratchets nothing."""
        self.air.follow(pressure_bar)

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
        air = self.air
        if out == air.out:
            return
        air.out = out
        self.pressure_loop.hold_integral = out
        hold = air.hold_bar
        if out or hold != hold:
            return
        p = self.known_pressure_bar(hold)
        if p < hold:
            air.hold_bar = p if p > 0.0 else 0.0

    def clear_findings(self) -> None:
        """Trust every signal again; the checks start afresh."""
        self.plausibility.clear()
        self.limit_monitor.stop_tracking()
        self.guards.reset()

    def reset(self) -> None:
        """The operator's reset of a latched fault: every signal trusted again; a
        started muscle closes its loop again from where it is, one never started holds
        its measured pressure."""
        self.clear_findings()
        self.air.release()
        self._chosen_for = -1
        if self._started:
            self.pressure_loop.reset(self.inputs.pressure_bar)
            self._safe_ramp = False
        else:
            self.hold_measured()

    # -- the setpoint source ---------------------------------------------------------------
    def _choose_source(self, state: int) -> None:
        """The setpoint source for the rig's `state` and this muscle's mode, profile,
        safe ramp and air hold, with what stays fixed while it is chosen (its slew
        outside a safe ramp, whether it is a safe state's). In FAULT or ESTOP the air
        hold if the air is cut, else the safe ramp, as in a stop's safe ramp (a safe
        state drops a length mode for good); a length mode (the valves position the
        length where they do that themselves); a pressure profile while RUNNING or
        LOAD_CHANGE; else the setpoint holds."""
        t = self.tick_values
        latched = state == S_FAULT or state == S_ESTOP
        safe = latched or self._safe_ramp
        lc = self.length_control
        if safe and lc.active:
            self.leave_length_mode()
        t.safe = safe
        t.air_hold = air_hold = latched and self.air.holding
        t.venting = t.positioning = False
        t.flow_bar = t.rate_bar_per_s = 0.0
        t.slew_bar_per_s = self._slew_limit_bar_per_s
        source: Stage = self.hold
        if air_hold:
            source = self.air
            env = self._envelope
            t.slew_bar_per_s = (env.estop_slew_bar_per_s if state == S_ESTOP
                                else env.safe_slew_bar_per_s)
        elif safe:
            source = self.safe_ramp
            self.safe_ramp.estop = state == S_ESTOP
        elif lc.active:
            lc.profile = self.profile
            source = lc
            if lc.position and self.actuation.positions_length:
                source = self.valves_position
                t.positioning = True
        elif (state == S_RUNNING or state == S_LOAD) and self.profile is not None:
            self.profile_follower.profile = self.profile
            source = self.profile_follower
        self._source = source
        self._chosen_for = state

    # -- the tick: read, update, write (`pamd.loop.control.controller.RigController.tick`)
    # -----------
    def read(self, now: float, dt: float, state: int) -> bool:
        """Read this tick's inputs and judge them (the hard limits, whether the pressure
        follows the command written last): what they find is `tick_values.fault` and
        `tick_values.finding`. Returns whether they found either."""
        t = self.tick_values
        t.state = state
        t.last_command_bar = self._valve_cmd_bar
        self.inputs.update(t, now, dt)
        air = self.air
        hold = air.hold_bar
        t.air_cut = air.out or (hold == hold and (state == S_FAULT or state == S_ESTOP))
        self.limit_monitor.update(t, now, dt)
        return t.fault is not None or t.finding is not None

    def update(self, now: float, dt: float) -> None:
        """This tick's setpoint (its source, chosen again when the state changed) and
        what the pressure loop wants of the command (a started muscle)."""
        if not self._started:
            return
        t = self.tick_values
        if t.state != self._chosen_for:
            self._choose_source(t.state)
        self._source.update(t, now, dt)
        self.pressure_loop.update(t, now, dt)

    def write(self, now: float, dt: float, entering: bool, rec: array[float]) -> str | None:
        """Bound, limit and write this tick's command, adapt, record. `entering`: the
        rig found a fault this tick (any muscle's): the safe state's entry, held to its
        invariants from the command written last, as is a tick that lost the pressure
        (the loop just opened: its command would jump from the PID's output to the
        setpoint). Returns the actuation's own fault (valves that do not act), or None."""
        t = self.tick_values
        if not self._started:
            self._record(rec, t)
            return None
        held = t.safe
        slew = t.slew_bar_per_s
        if not held and (entering or not t.pressure_ok):
            held = True
            slew = self._envelope.safe_slew_bar_per_s
        t.held = held
        t.step_bar = slew * dt
        if t.last_command_bar != t.last_command_bar:  # nothing written yet
            t.last_command_bar = t.command_bar
        self.guards.update(t, now, dt)
        if held:  # the limiter's floor, which it reads only then
            t.floor_bar = (0.0 if t.state == S_ESTOP and slew == math.inf
                           else self._safe_pressure_bar)
        wanted = t.command_bar
        self.limiter.update(t, now, dt)
        u = self._valve_cmd_bar = t.command_bar
        if u != wanted:
            self.pressure_loop.unwind(u, wanted)
        if t.flags & F_AT_LIMIT or self.guards.holding_back:  # held back at a soft limit
            self._held_at_limit(t, now)
        self._actuate(t, now, dt)
        if self.adaptation.enabled:
            self.adaptation.update(t, now, dt)
        self._record(rec, t)
        return t.fault

    def _held_at_limit(self, t: MuscleTick, now: float) -> None:
        """A profile held back at a soft limit for more than a second: the report the
        rig controller says (rare path)."""
        state = t.state
        report = self.guards.held_at_limit(now, t.flags, state == S_RUNNING or state == S_LOAD,
                                           t.setpoint_bar, t.command_bar)
        if report is not None:
            self.limit_report = report

    def _actuate(self, t: MuscleTick, now: float, dt: float) -> None:
        """What the actuation acts on, then the actuation: vent at a safe pressure of 0
        once the command is there; in a held tick never vent below the safe pressure
        (the air hold vents nothing anyway) nor position the length; holding the air,
        no pressure is acted on (on/off valves both shut, an exhaust valve shut, the
        regulator at the held command)."""
        venting, held, air_hold = t.venting, t.held, t.air_hold
        t.vent = venting and t.command_bar <= VENT_BELOW_BAR
        t.position_valves = t.positioning and not held
        hi, top = t.hi_bar, self._max_pressure_bar
        t.ceiling_bar = top if hi > top else hi
        t.valve_floor_bar = (self._safe_pressure_bar if held and not venting and not air_hold
                             else -math.inf)
        t.valve_pressure_bar = NAN if air_hold else t.pressure_bar
        t.fault = None
        self.actuation.update(t, now, dt)

    def _record(self, rec: array[float], t: MuscleTick) -> None:
        """The muscle's slots of the tick record (plain float stores)."""
        b = self._base
        lc, pid = self.length_control, self._pid
        rec[b + M_PRESSURE] = t.pressure_bar
        rec[b + M_FORCE] = t.force_n
        rec[b + M_LENGTH] = t.length_mm
        rec[b + M_CONTRACTION] = t.contraction
        rec[b + M_VELOCITY] = t.velocity_mm_s
        # where the valves position the length (on/off valves in mode position, seed
        # 004's sliding mode) there is no pressure setpoint, and none recorded
        rec[b + M_SETPOINT] = NAN if t.positioning else t.setpoint_bar
        rec[b + M_FEEDFORWARD] = lc.feedforward_bar
        rec[b + M_PID_P] = pid.p
        rec[b + M_PID_I] = pid.i
        rec[b + M_PID_D] = pid.d
        rec[b + M_VALVE_CMD] = self._valve_cmd_bar
        rec[b + M_TARGET_LENGTH] = lc.target_length_mm
        rec[b + M_TARGET_FORCE] = lc.target_force_n
        rec[b + M_SAFE_PRESSURE] = self._safe_pressure_bar
        rec[b + M_MODE] = self._mode
        rec[b + M_FLAGS] = t.flags
        ad = self.adaptation
        rec[b + M_ADAPT_DRIFT] = ad.drift_bar
        rec[b + M_ADAPT_STATE] = ad.state

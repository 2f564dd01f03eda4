"""The `control` section of the rig configuration: the pressure loop's PID and rate
feedforward, and the length modes' position loop, dynamic feedforward and iterative
learning (`pamd.config.schema` holds the rest)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pamd.wire.schema.engine import spec

# Gain caps (what `pamd tune` always satisfies: `pamd.loop.control.tuning.simc_pi` slows its
# closed loop until they hold), bounds of what a gain can mean: within them, whether a
# gain set is stable on the muscle's plant is judged against that plant
# (`pamd.config.gains`, the closed loop at the loop's rate). Pressure loop: kp 20 makes
# a 5 mbar sensor quantum a 0.1 bar valve step; ki 2000/s integrates a whole error in
# half a millisecond, faster than the 1 kHz loop can act on it; kd 0.1 s turns a 1 bar/s
# measured rate into 0.1 bar. Position loop: 5 bar/mm asks the whole pressure range
# for a 1 mm error; 100 bar/(mm s) and 1 bar s/mm likewise. Seed 003's incremental PID
# has no cap of its own: its gains are per sample (their meaning moves with its sample
# period), and its Table 3 (Kp 9.5) is judged on the plant like any other.
PID_KP_MAX = 20.0
PID_KI_MAX_PER_S = 2000.0
PID_KD_MAX_S = 0.1
POSITION_KP_MAX_BAR_PER_MM = 5.0
POSITION_KI_MAX_BAR_PER_MM_S = 100.0
POSITION_KD_MAX_BAR_S_PER_MM = 1.0
#: Fastest setpoint slew: a proportional regulator (Festo VPPM class) fills a DMSP-20
#: at a few tens of bar/s at most, so at 500 bar/s (what `pamd tune`'s identification
#: run sets, "a step is a step") the regulator, not the limit, sets the pace; above
#: it the limit limits nothing (the config does not state the regulator's own rate).
SLEW_LIMIT_MAX_BAR_PER_S = 500.0


@dataclass(frozen=True, kw_only=True)
class PressurePlantConfig:
    """The pressure loop's plant, K e^(-theta s) / (tau s + 1): regulator setpoint ->
    measured pressure (what `pamd tune` fits)."""

    gain_bar_per_bar: float = spec(doc="Static gain: the settled change of the measured "
                                   "pressure per bar of regulator setpoint.",
                                   unit="bar/bar", gt=0.0, max=10.0)
    lag_s: float = spec(doc="Time constant of the first-order lag.", unit="s", gt=0.0,
                        max=10.0)
    dead_time_s: float = spec(doc="Dead time between the command and the measured "
                              "response (the devices' and the tick's own delays "
                              "included, as recorded).", unit="s", min=0.0, max=10.0)


@dataclass(frozen=True, kw_only=True)
class PositionPlantConfig:
    """The position loop's plant: pressure setpoint -> measured length, the pressure
    loop closed (what `pamd tune --loop position` fits)."""

    gain_mm_per_bar: float = spec(doc="Static gain: the settled change of the length per "
                                  "bar of pressure setpoint (negative: more pressure, "
                                  "shorter; less than 1 um per bar is no response).",
                                  unit="mm/bar", min=-1000.0, max=-0.001)
    lag_s: float = spec(doc="Time constant of the first-order lag.", unit="s", gt=0.0,
                        max=10.0)
    dead_time_s: float = spec(doc="Dead time between the setpoint and the measured "
                              "length.", unit="s", min=0.0, max=10.0)


#: The plants the gains are judged against where the config states none: measured, on
#: the simulated rig (a DMSP-20-200 behind a VPPM-class regulator, 30 kg), by the same
#: identification runs as `pamd tune` (bench/tune_pressure_loop.py; config/sim.yaml's
#: gains were derived from them), never from the simulator's parameters.
DEFAULT_PRESSURE_PLANT = PressurePlantConfig(gain_bar_per_bar=0.95, lag_s=0.0125,
                                             dead_time_s=0.0128)
DEFAULT_POSITION_PLANT = PositionPlantConfig(gain_mm_per_bar=-6.6, lag_s=0.0316,
                                             dead_time_s=0.0362)
_DEFAULT_PLANT_DOC = ("null: the default plant, the simulated DMSP-20-200's measured "
                      "response (at 30 kg)")


@dataclass(frozen=True, kw_only=True)
class PidConfig:
    kp: float = spec(0.516, "Proportional gain (default: SIMC PI on the simulated rig's "
                     "measured step response, bench/tune_pressure_loop.py).", unit="bar/bar",
                     min=0.0, max=PID_KP_MAX)
    ki_per_s: float = spec(41.2, "Integral gain.", unit="1/s", min=0.0, max=PID_KI_MAX_PER_S)
    kd_s: float = spec(0.0, "Derivative gain (on measurement).", unit="s", min=0.0,
                       max=PID_KD_MAX_S)
    derivative_filter_hz: float = spec(30.0, "Cut-off of the derivative's low-pass filter.",
                                       unit="Hz", gt=0.0)
    integral_limit_bar: float = spec(1.0, "Anti-windup clamp of the integral term.",
                                     unit="bar", min=0.0)
    output_limit_bar: float = spec(1.5, "Largest correction the PID adds to the setpoint.",
                                   unit="bar", min=0.0)


@dataclass(frozen=True, kw_only=True)
class PositionPidConfig:
    kp_bar_per_mm: float = spec(0.0656, "Proportional gain on the length error (measured - "
                                "target: too long means more pressure). Default: SIMC PI "
                                "on the simulated rig's measured pressure -> length step "
                                "response at 30 kg (bench/tune_pressure_loop.py).",
                                unit="bar/mm", min=0.0, max=POSITION_KP_MAX_BAR_PER_MM)
    ki_bar_per_mm_s: float = spec(2.08, "Integral gain.", unit="bar/(mm s)", min=0.0,
                                  max=POSITION_KI_MAX_BAR_PER_MM_S)
    kd_bar_s_per_mm: float = spec(0.0, "Derivative gain (on the measured length).",
                                  unit="bar s/mm", min=0.0, max=POSITION_KD_MAX_BAR_S_PER_MM)
    derivative_filter_hz: float = spec(10.0, "Cut-off of the derivative's low-pass filter.",
                                       unit="Hz", gt=0.0)
    integral_limit_bar: float = spec(6.0, "Anti-windup clamp of the integral term (it carries "
                                     "the whole pressure when there is no model).", unit="bar",
                                     min=0.0)
    output_limit_bar: float = spec(6.0, "Largest correction the position loop adds to the "
                                   "model's pressure.", unit="bar", min=0.0)


@dataclass(frozen=True, kw_only=True)
class IlcConfig:
    gain: float = spec(0.5, "Learning gain: each cycle, the correction of the position "
                       "loop's target at a phase grows by this times the length error one "
                       "`lead_s` later (mm per mm; converges for 0 < gain < 2 where the "
                       "closed position loop follows its target).", min=0.0, max=2.0)
    gain_d_s: float = spec(0.0, "Learning gain on the error's rate of change.", unit="s",
                           min=0.0)
    lead_s: float = spec(0.068, "Phase lead of the learning update: the delay from the "
                         "position loop's target to the length, i.e. the position loop's "
                         "dead time + lag that `pamd tune --loop position` measures "
                         "(default: 36.1 + 31.5 ms, the simulated DMSP-20-200 at 30 kg). "
                         "Applied exactly, not rounded to `resolution_s`.", unit="s",
                         min=0.0, max=5.0)
    cutoff_hz: float = spec(6.0, "Cut-off of the Q-filter, the zero-phase low-pass "
                            "applied to the whole learned correction once a cycle (gain "
                            "1/2 here): what the learning may correct. Keep it below the "
                            "position loop's bandwidth and below 1 / (4 x the uncertainty "
                            "of lead_s).", unit="Hz", gt=0.0)
    forgetting: float = spec(0.0, "Share of the learned correction forgotten per cycle "
                             "(bounds it against slow drift the Q-filter passes).", min=0.0,
                             max=0.5)
    limit_mm: float = spec(10.0, "Largest learned correction of the length target.",
                           unit="mm", min=0.0)
    resolution_s: float = spec(0.01, "Time resolution of the learned correction over a "
                               "cycle (bins, read between their centres by linear "
                               "interpolation).", unit="s", gt=0.0, max=2.0)


@dataclass(frozen=True, kw_only=True)
class IncrementalPidConfig:
    method: Literal[1, 2] = spec(
        2, "Seed 003's control method: 1, the increment alone is the compensation (sec. "
        "3.3, u(k) = du(k)); 2, the increments accumulated (sec. 3.4, u(k) = u(k-1) + "
        "du(k)). du(k) = Kp (e(k) - e(k-1)) + Ki e(k) + Kd (e(k) - 2 e(k-1) + e(k-2)).")
    sample_period_s: float | None = spec(
        None, "The controller's sample period: the increments are computed this often (the "
        "gains are per sample). Null: every tick (1 / loop.rate_hz), where method 2 with "
        "the derived gains is the position PID itself (seed 003 does not state its "
        "period).", unit="s", gt=0.0, max=1.0)
    kp_bar_per_mm: float | None = spec(
        None, "Kp, on the error's change per sample. Null: derived from `position.pid` "
        "(method 2: kp; method 1: kd / sample_period_s). No cap: the gains are judged "
        "against the position plant at this sample period (`control.position.plant`).",
        unit="bar/mm", min=0.0)
    ki_bar_per_mm: float | None = spec(
        None, "Ki, on the error. Null: derived from `position.pid` (method 2: ki_bar_per_mm_s "
        "x sample_period_s, the same integral action; method 1: kp, since its Ki e(k) is "
        "a proportional term). Seed 003's Table 3 (its own muscle and units): method 1 "
        "9.5/1.3/0.5, method 2 5.0/0.5/0.1.", unit="bar/mm", min=0.0)
    kd_bar_per_mm: float | None = spec(
        None, "Kd, on the error's second difference per sample. Null: derived from "
        "`position.pid` (kd_bar_s_per_mm / sample_period_s for method 2, 0 for method 1).",
        unit="bar/mm", min=0.0)
    output_limit_bar: float = spec(6.0, "Largest compensation it adds to the model's "
                                   "pressure.", unit="bar", min=0.0)

    def period_s(self, tick_period_s: float) -> float:
        return tick_period_s if self.sample_period_s is None else self.sample_period_s

    def gains(self, pid: PositionPidConfig, tick_period_s: float
              ) -> tuple[float, float, float]:
        """(Kp, Ki, Kd) per sample: as given, else derived from the position PID."""
        t = self.period_s(tick_period_s)
        if self.method == 2:
            kp, ki, kd = pid.kp_bar_per_mm, pid.ki_bar_per_mm_s * t, pid.kd_bar_s_per_mm / t
        else:
            kp, ki, kd = pid.kd_bar_s_per_mm / t, pid.kp_bar_per_mm, 0.0
        return (kp if self.kp_bar_per_mm is None else self.kp_bar_per_mm,
                ki if self.ki_bar_per_mm is None else self.ki_bar_per_mm,
                kd if self.kd_bar_per_mm is None else self.kd_bar_per_mm)


@dataclass(frozen=True, kw_only=True)
class PositionConfig:
    pid: PositionPidConfig = spec(PositionPidConfig(), "Outer position loop (position "
                                  "mode): corrects what the model misses.")
    feedback: Literal["pid", "incremental"] = spec(
        "pid", "position mode's feedback: `pid`, the PID of `position.pid`; "
        "`incremental`, seed 003's incremental PID in velocity form (Method 1 or 2, "
        "`position.incremental`).")
    incremental: IncrementalPidConfig = spec(IncrementalPidConfig(), "Seed 003's "
                                             "incremental PID (`feedback: incremental`).")
    plant: PositionPlantConfig | None = spec(
        None, "The position loop's plant, pressure setpoint -> measured length with the "
        "pressure loop closed, first order plus dead time as `pamd tune --loop position` "
        "fits it (`--save` writes it here). The position gains (`pid`, or `incremental` "
        "at its sample period) are judged against it: a closed loop that is unstable or "
        "has too little margin is refused, naming its gain and phase margins, unless "
        "only its integral makes it so (friction holds a muscle near its target, where "
        "the integral acts, to a fraction of the fitted gain): then it loads with a "
        "warning (docs/how-to/tune.md, 'Gains judged against stability'). "
        + _DEFAULT_PLANT_DOC + ": gain -6.6 mm/bar, lag 31.6 ms, dead time 36.2 ms.")
    max_rate_per_s: float | None = spec(
        None, "Fastest change of a length target, contraction (fraction) per second; "
        "faster length profiles and setpoint ramps are refused, naming the frequency that "
        "would pass. null (default): derived per muscle from what it can follow at its "
        "configured load: the slew limit times the least contraction per bar of its usable "
        "range (force model), bounded by the pressure loop's bandwidth (a sine over the "
        "whole range at 1 / (2 pi rate_feedforward_s)); `pamd check-config` prints it.",
        unit="1/s", gt=0.0, max=1.0)
    force_filter_s: float = spec(0.5, "position mode: time constant of the low-pass on the "
                                 "measured force fed to the model (the model is a "
                                 "quasi-static inverse; the force's fast part would close a "
                                 "loop through it).", unit="s", gt=0.0, max=10.0)
    bumpless_s: float = spec(1.0, "length_force mode: the pressure difference found at a "
                             "mode change or model swap fades with this time constant.",
                             unit="s", gt=0.0)
    ilc: IlcConfig = spec(IlcConfig(), "Iterative learning across repeated cycles "
                          "(position mode with `ilc: true`; seed 003's PID-type ILC).")
    length_response_s: float = spec(
        0.0678, "Dead time + lag of the measured length after a pressure setpoint step, "
        "the pressure loop closed with its rate feedforward (the position loop's FOPDT "
        "fit: `pamd tune --loop position`, bench/tune_pressure_loop.py --loop position; "
        "36.2 + 31.6 ms on the simulated rig at 30 kg). Sets the default `preview_s`.",
        unit="s", min=0.0, max=2.0)
    preview_s: float | None = spec(
        None, "position mode: the model's feedforward (and the dynamic terms) are evaluated "
        "on the length profile this far ahead, so the pressure is there when the length is "
        "due; the position PID still compares with the present target. Null: "
        "`length_response_s` - `control.rate_feedforward_s`, the setpoint -> length delay "
        "less the pressure loop's dead time + lag, which the rate feedforward (fed the "
        "model's planned rate) already cancels; 0.0429 s on the simulated rig. 0: no "
        "preview.", unit="s", min=0.0, max=2.0)
    planned_rate: bool = spec(
        True, "position mode: the setpoint's rate fed to the pressure loop's rate "
        "feedforward is the model's derivative along the planned motion (dP/dL dL/dt + "
        "dP/dv dv/dt at the preview, plus the outer loop's filtered rate) rather than the "
        "filtered numeric derivative of the whole setpoint (which lags by its 50 ms "
        "window). A stateful model keeps the numeric derivative.")
    flow_feedforward_bar_s_per_mm: float = spec(
        0.0, "position mode: added to the valve command per mm/s of planned shortening "
        "(at the preview): the air a moving muscle draws (contracting) or returns makes "
        "its pressure sag or rise behind the regulator's lag. Identified on the rig, never "
        "from a simulator's parameters: the slope of the pressure loop's correction "
        "against the length rate on a recorded position run (bench/position_fast.py "
        "fits it on a validation run). 0: off.", unit="bar s/mm", min=0.0, max=1.0)
    model_sweep_hz: float | None = spec(
        None, "position mode: the frequency of the sweeps the model was trained on (e.g. "
        "0.05 for the 0.05 Hz sweeps of the walk-through). Then a periodic length "
        "profile at f Hz feeds the model's velocity input on a time axis stretched to "
        "its training sweeps (its filter window and the velocity times model_sweep_hz / "
        "f): the model sees the hysteresis branch at the same phase of the stroke as in "
        "training, not a quarter period late at 1 Hz. Null: the velocity as filtered in "
        "training, at any speed.", unit="Hz", gt=0.0, max=100.0)
    force_input: Literal["measured", "planned"] = spec(
        "measured", "position mode: the model's force input. `measured`: the measured "
        "force through the `force_filter_s` low-pass. `planned`: the hanging load's "
        "weight plus its inertia on the planned motion at the preview, load_kg (g - "
        "d2L/dt2), no lag (a hanging load only; bench/position_fast.py measures it).")


#: What the loop does when the model's inputs leave its training domain
#: (`pamd.models.domain`): fade its feedforward to the position PID alone, say it only, or
#: not judge at all.
OFF_DATA_POLICIES = ("fade", "warn", "off")


@dataclass(frozen=True, kw_only=True)
class FeedforwardConfig:
    off_data: Literal["fade", "warn", "off"] = spec(
        "fade", "The model's inputs outside its training domain (the force beyond its "
        "outermost trained loads, or a length, velocity or pressure not seen at that force; "
        "a load between two trained loads is inside): `fade`, the feedforward fades to the "
        "position PID alone there (the PID's integral takes over what the model gave, so "
        "the setpoint does not jump) and returns when the inputs are back; `warn`, counted "
        "and said only; `off`, not judged. Either way once said as a `feedforward` event "
        "and counted in the run summary. In length_force mode (no PID to fade to) `fade` "
        "acts as `warn`. `pamd run --off-data` overrides it.")
    fade_s: float = spec(0.5, "How long the feedforward takes to fade out when its inputs "
                         "leave the training domain, and to come back.", unit="s", gt=0.0,
                         max=60.0)


@dataclass(frozen=True, kw_only=True)
class ControlConfig:
    pid: PidConfig = spec(PidConfig(), "PID pressure loop gains.")
    plant: PressurePlantConfig | None = spec(
        None, "The pressure loop's plant, regulator setpoint -> measured pressure, first "
        "order plus dead time as `pamd tune` fits it (`--save` writes it here). The "
        "pressure gains are judged against it: a closed loop that is unstable or has too "
        "little margin is refused, naming its gain and phase margins "
        "(docs/how-to/tune.md, 'Gains judged against stability'); "
        "`safety.tracking_time_s` must outlast its response. " + _DEFAULT_PLANT_DOC
        + ": gain 0.95 bar/bar, lag 12.5 ms, dead time 12.8 ms.")
    position: PositionConfig = spec(PositionConfig(), "The length modes (length_force, "
                                    "position): outer position loop and iterative learning.")
    feedforward: FeedforwardConfig = spec(FeedforwardConfig(), "The inverse model's "
                                          "feedforward off its training data.")
    rate_feedforward_s: float = spec(
        0.0253, "The setpoint's rate times this is added to the valve command; it cancels "
        "the pressure loop's dead time plus lag, both measured from a step response "
        "(bench/tune_pressure_loop.py).", unit="s", min=0.0, max=1.0)
    slew_limit_bar_per_s: float = spec(5.0, "Fastest allowed setpoint change; faster "
                                       "profiles are refused.", unit="bar/s", gt=0.0,
                                       max=SLEW_LIMIT_MAX_BAR_PER_S)

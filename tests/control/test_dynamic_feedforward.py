"""Position mode's feedforward that knows the motion (issue 16 item 1): the model on the
previewed reference, the setpoint's rate from the model's derivative along the planned
motion, the flow term, the planned force; on a known (linear) model, then on the
simulated rig at 0.5 Hz."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pamd.config import LoadedConfig
from pamd.config.control_schema import PositionConfig, PositionPidConfig
from pamd.loop.control.feedforward import Feedforward, LoadedModel
from pamd.loop.control.length_control import LengthControl, preview_s_of
from pamd.loop.harness import Harness
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.models.anfis import TrainingOptions, fit
from pamd.models.contract import InverseModel
from pamd.muscle_type import GRAVITY_M_S2
from pamd.profiles import Profile, ProfilePoint, ProfileSpec
from pamd.wire.tick import Mode, State

S_RUNNING = int(State.RUNNING)
#: the known model: p = 3 + DP_DF (F - 295) + DP_DL (L - 180), bar
DP_DF, DP_DL = 0.01, -0.1
DT = 0.001


@pytest.fixture(scope="module")
def linear_model() -> InverseModel:
    """A (force, length) model fitted on the linear map above (ANFIS's consequents are
    linear: it is exact there)."""
    rng = np.random.default_rng(3)
    X = np.c_[rng.uniform(150.0, 450.0, 400), rng.uniform(150.0, 205.0, 400)]
    y = 3.0 + DP_DF * (X[:, 0] - 295.0) + DP_DL * (X[:, 1] - 180.0)
    res = fit(X, y, TrainingOptions(n_mfs=2, epochs=5), input_names=["force_n", "length_mm"],
              input_units=["N", "mm"], output_name="pressure_bar", output_unit="bar")
    return res.model


def model_p(f: float, ln: float) -> float:
    return 3.0 + DP_DF * (f - 295.0) + DP_DL * (ln - 180.0)


def control(cfg: LoadedConfig, model: InverseModel, **position: object) -> LengthControl:
    """A LengthControl in position mode at 175 mm / 294 N, the outer PID off (so the
    setpoint is the model's pressure alone)."""
    pos = replace(cfg.rig.control.position, pid=PositionPidConfig(
        kp_bar_per_mm=0.0, ki_bar_per_mm_s=0.0), **position)  # type: ignore[arg-type]
    env = replace(MuscleEnvelope.from_config(cfg, "m1"), slew_limit_bar_per_s=1e3)
    lc = LengthControl(env, pos, Feedforward(model), rate_feedforward_s=0.0255)
    lc.set_load(30.0)
    lc.enter(Mode.POSITION, True, False, from_pressure=True, length_mm=175.0, force_n=294.0,
             setpoint_bar=model_p(294.0, 175.0))
    return lc


def sine(freq_hz: float = 0.5) -> Profile:
    """5-20 % contraction (190 -> 160 mm), from mid-range: no lead-in."""
    spec = ProfileSpec(shape_name="sine", min_bar=0.05, max_bar=0.20, freq_hz=freq_hz,
                       lead_in_bar_per_s=0.1)
    return Profile(spec, 0.0, 0.125, 0.5)


def run(lc: LengthControl, prof: Profile, until_s: float, force_n: float = 294.0) -> float:
    """Tick `lc` on the profile to `until_s`, the length on target; the last setpoint."""
    sp = lc.last_setpoint
    t = 0.0
    while t < until_s - 1e-9:
        t += DT
        sp = lc.step(t, DT, S_RUNNING, sp, prof, lc.target_length_mm
                     if lc.target_length_mm == lc.target_length_mm else 175.0, force_n)
    return sp


def length_at(prof: Profile, t: float) -> float:
    pt = ProfilePoint()
    prof.evaluate(t, pt)
    return 200.0 * (1.0 - pt.value)


def test_profile_evaluate_leaves_the_running_profile_alone() -> None:
    prof = sine()
    prof.sample(0.3)
    before = (prof.value, prof.rate, prof.accel, prof.cycle, prof.done)
    pt = ProfilePoint()
    prof.evaluate(2.4, pt)
    assert (prof.value, prof.rate, prof.accel, prof.cycle, prof.done) == before
    w = 2 * math.pi * 0.5
    assert pt.value == pytest.approx(0.125 + 0.075 * math.sin(w * 2.4))
    assert pt.rate == pytest.approx(0.075 * w * math.cos(w * 2.4))
    assert pt.accel == pytest.approx(-0.075 * w * w * math.sin(w * 2.4))
    assert pt.cycle == 1 and not pt.done


def test_the_model_sees_the_reference_preview_s_ahead(
        sim_config: Callable[..., LoadedConfig], linear_model: InverseModel) -> None:
    cfg = sim_config()
    for preview in (0.0, 0.08):
        lc = control(cfg, linear_model, preview_s=preview)
        prof = sine()
        run(lc, prof, 0.1)
        # the PID (and the recorded target) keep the present target ...
        assert lc.target_length_mm == pytest.approx(length_at(prof, 0.1))
        # ... the model the one `preview` ahead (the force: the low-passed 294 N)
        ahead = length_at(prof, 0.1 + preview)
        assert lc.feedforward_bar == pytest.approx(model_p(294.0, ahead), abs=2e-3)
    # the preview moved the pressure earlier, not later: at 0.1 s the muscle shortens
    # fast (contracting), so the pressure ahead is higher than the present one
    assert lc.feedforward_bar > model_p(294.0, length_at(prof, 0.1)) + 0.2


def test_default_preview_is_the_length_response_less_the_rate_feedforward(
        sim_config: Callable[..., LoadedConfig]) -> None:
    pos = sim_config().rig.control.position
    assert pos.preview_s is None
    assert preview_s_of(pos, 0.0253) == pytest.approx(0.0678 - 0.0253)
    assert preview_s_of(replace(pos, preview_s=0.1), 0.0255) == 0.1
    assert preview_s_of(PositionConfig(length_response_s=0.01), 0.0255) == 0.0


def test_setpoint_rate_is_the_models_derivative_along_the_planned_motion(
        sim_config: Callable[..., LoadedConfig], linear_model: InverseModel) -> None:
    """dP/dL x dL/dt at the preview, no lag: at 0.5 Hz the planned rate is in phase with
    the motion ahead, where the numeric derivative lags by its 50 ms filter."""
    cfg = sim_config()
    planned = control(cfg, linear_model, preview_s=0.05)
    numeric = control(cfg, linear_model, preview_s=0.05, planned_rate=False)
    for t in (0.9, 1.3):
        prof_a, prof_b = sine(), sine()
        run(planned, prof_a, t)
        run(numeric, prof_b, t)
        pt = ProfilePoint()
        prof_a.evaluate(t + 0.05, pt)
        dl_dt = -200.0 * pt.rate  # mm/s
        assert planned.setpoint_rate_bar_per_s == pytest.approx(DP_DL * dl_dt, rel=0.01,
                                                                abs=0.01)
        # the filtered numeric derivative lags: about 50 ms behind the planned one
        pt_lag = ProfilePoint()
        prof_a.evaluate(t + 0.05 - 0.05, pt_lag)
        assert numeric.setpoint_rate_bar_per_s == pytest.approx(
            DP_DL * -200.0 * pt_lag.rate, rel=0.05, abs=0.02)
        planned = control(cfg, linear_model, preview_s=0.05)
        numeric = control(cfg, linear_model, preview_s=0.05, planned_rate=False)


def test_flow_term_adds_pressure_while_the_muscle_shortens(
        sim_config: Callable[..., LoadedConfig], linear_model: InverseModel) -> None:
    lc = control(sim_config(), linear_model, preview_s=0.05,
                 flow_feedforward_bar_s_per_mm=0.002)
    prof = sine()
    run(lc, prof, 0.2)  # rising contraction: the muscle shortens (dL/dt < 0)
    pt = ProfilePoint()
    prof.evaluate(0.25, pt)
    assert lc.flow_bar == pytest.approx(0.002 * 200.0 * pt.rate)
    assert lc.flow_bar > 0.05
    run(lc, prof, 1.2 - 0.2)  # t = 1.2 s: it lengthens, the term vents
    assert lc.flow_bar < -0.05


def test_planned_force_is_the_loads_weight_plus_its_inertia(
        sim_config: Callable[..., LoadedConfig], linear_model: InverseModel) -> None:
    """`force_input: planned`: 30 kg x (g - d2L/dt2) at the preview, whatever the load
    cell says (here a constant 250 N)."""
    lc = control(sim_config(), linear_model, preview_s=0.05, force_input="planned")
    prof = sine(1.0)
    run(lc, prof, 0.2, force_n=250.0)
    pt = ProfilePoint()
    prof.evaluate(0.25, pt)  # the top of the stroke (most contracted)
    acc_m_s2 = -0.2 * pt.accel  # length's acceleration: contraction x 200 mm, in m/s^2
    f = 30.0 * (GRAVITY_M_S2 - acc_m_s2)
    assert f < 30.0 * GRAVITY_M_S2 - 10.0  # the load decelerates at the top: pulls less
    assert lc.feedforward_bar == pytest.approx(
        model_p(f, 200.0 * (1.0 - pt.value)), abs=2e-3)


def test_model_sweep_hz_puts_the_velocity_input_on_the_training_sweeps_time_axis(
        sim_config: Callable[..., LoadedConfig]) -> None:
    """A model trained on 0.05 Hz sweeps, a 0.5 Hz profile: the model's velocity input is
    the previewed length filtered with a window 0.05 / 0.5 of its own, times 0.1 (the
    velocity a 0.05 Hz sweep had at that phase of the stroke)."""
    rng = np.random.default_rng(4)
    X = np.c_[rng.uniform(150.0, 450.0, 600), rng.uniform(150.0, 205.0, 600),
              rng.uniform(-10.0, 10.0, 600)]
    y = 3.0 + DP_DF * (X[:, 0] - 295.0) + DP_DL * (X[:, 1] - 180.0) + 0.05 * X[:, 2]
    res = fit(X, y, TrainingOptions(n_mfs=2, epochs=5),
              input_names=["force_n", "length_mm", "velocity_mm_s"],
              input_units=["N", "mm", "mm/s"], output_name="pressure_bar", output_unit="bar",
              derived_inputs={"velocity_mm_s": {"derived_from": "length_mm", "window_s": 3.0}})
    cfg = sim_config()
    lc = control(cfg, res.model, preview_s=0.05, model_sweep_hz=0.05)
    prof = sine(0.5)
    run(lc, prof, 1.3)
    assert lc.target_vel.window_s == pytest.approx(0.3)
    v, prev, t = 0.0, 175.0, 0.0
    while t < 1.3 - 1e-9:  # the filter the tick runs, on the previewed length
        t += DT
        ln = length_at(prof, t + 0.05)
        v += DT / (0.3 + DT) * ((ln - prev) / DT - v)
        prev = ln
    assert abs(v) > 20.0  # fast: the 0.5 Hz stroke
    expected = model_p(294.0, length_at(prof, 1.35)) + 0.05 * 0.1 * v
    assert lc.feedforward_bar == pytest.approx(expected, abs=5e-3)
    # without it: the model's own 3 s window and the velocity as filtered
    plain = control(cfg, res.model, preview_s=0.05)
    run(plain, sine(0.5), 1.3)
    assert plain.target_vel.window_s == pytest.approx(3.0)
    assert abs(plain.feedforward_bar - lc.feedforward_bar) > 0.05


# -- on the simulated rig -----------------------------------------------------------------
FAST = {"slew_limit_bar_per_s": 20.0, "position": {"max_rate_per_s": 0.5}}
BEFORE = {"preview_s": 0.0, "planned_rate": False}


def track_05hz(cfg: LoadedConfig, model: Path | None, cycles: int = 4) -> float:
    """Length RMSE (mm) of a 0.5 Hz sine over 5-20 % after its first two cycles."""
    h = Harness(cfg, {} if model is None else {"m1": LoadedModel.read(
        str(model), cfg.muscle("m1"), cfg.limits["m1"])})
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=model is not None)["ok"]
    v = h.cmd("profile", muscle="m1", kind="sine", min_contraction=0.05,
              max_contraction=0.20, freq_hz=0.5, cycles=cycles)
    assert v["ok"], v
    m = h.m1
    assert m.profile is not None
    t_from = h.t + m.profile.lead_in_s + 2.0 / 0.5
    sq, n = 0.0, 0
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(h.period_s)
        if h.t >= t_from and m.profile is not None:
            e = m.length_mm - m.target_length_mm
            sq, n = sq + e * e, n + 1
    h.rig.close()
    return math.sqrt(sq / n)


def test_position_at_half_a_hertz_beats_the_pid_alone(
        sim_config: Callable[..., LoadedConfig], static_model: Path) -> None:
    """The flow plant, 30 kg, 5-20 % at 0.5 Hz (bench/position_fast.py's test case, with
    the frictionless map model in place of the trained one)."""
    pid_alone = track_05hz(sim_config(control=FAST), None)
    before = track_05hz(sim_config(control={**FAST, "position": {
        **FAST["position"], **BEFORE}}), static_model)
    dynamic = track_05hz(sim_config(control={**FAST, "position": {
        **FAST["position"], "preview_s": 0.08, "force_input": "planned"}}), static_model)
    print(f"0.5 Hz RMSE: PID alone {pid_alone:.3f} mm, model + PID {before:.3f} mm, "
          f"+ preview/dynamic {dynamic:.3f} mm")
    assert pid_alone == pytest.approx(PID_ALONE_MM, rel=0.1)
    assert dynamic <= DYNAMIC_MM * 1.1
    assert dynamic < before
    assert dynamic < pid_alone / FACTOR


PID_ALONE_MM, DYNAMIC_MM, FACTOR = 2.28, 0.741, 3.0


def test_entry_with_everything_on_is_bumpless(
        sim_config: Callable[..., LoadedConfig], static_model: Path) -> None:
    cfg = sim_config(control={**FAST, "position": {
        **FAST["position"], "preview_s": 0.08, "force_input": "planned",
        "flow_feedforward_bar_s_per_mm": 0.002}})
    h = Harness(cfg, {"m1": LoadedModel.read(str(static_model), cfg.muscle("m1"),
                                             cfg.limits["m1"])})
    h.step(0.05)
    assert h.cmd("setpoint", muscle="m1", bar=3.0)["ok"]
    h.step(2.0)
    sp, u = h.m1.setpoint_bar, h.m1.valve_cmd_bar
    assert h.cmd("mode", muscle="m1", mode="position")["ok"]
    h.step(0.01)
    assert h.m1.setpoint_bar == pytest.approx(sp, abs=0.02)
    assert h.m1.valve_cmd_bar == pytest.approx(u, abs=0.05)
    assert h.m1.length_control.flow_bar == 0.0
    h.rig.close()


def test_the_flow_term_reaches_the_valve_command(
        sim_config: Callable[..., LoadedConfig], static_model: Path) -> None:
    """The muscle adds `flow_bar` after its pressure loop: the valve command is the
    setpoint + rate feedforward + PID + the flow term."""
    cfg = sim_config(control={**FAST, "position": {
        **FAST["position"], "flow_feedforward_bar_s_per_mm": 0.002}})
    h = Harness(cfg, {"m1": LoadedModel.read(str(static_model), cfg.muscle("m1"),
                                             cfg.limits["m1"])})
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position")["ok"]
    assert h.cmd("profile", muscle="m1", kind="sine", min_contraction=0.05,
                 max_contraction=0.20, freq_hz=0.5, cycles=3)["ok"]
    m = h.m1
    assert m.profile is not None
    h.step(m.profile.lead_in_s + 2.1)  # the second cycle's rise: shortening fast
    lc, pid = m.length_control, m.pressure_loop.pid
    assert lc.flow_bar > 0.05
    loop = m.setpoint_bar + cfg.rig.control.rate_feedforward_s * \
        lc.setpoint_rate_bar_per_s + pid.p + pid.i + pid.d
    assert m.valve_cmd_bar == pytest.approx(loop + lc.flow_bar, abs=1e-9)
    h.rig.close()

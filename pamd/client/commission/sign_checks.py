"""The signs and scaling a commissioning run checks, each on what physics says must
hold; a wrong one stops the run (`CommissionRefused`) naming the signal and what to
check, before anything else moves.

- **Every signal updates** at rest: a new sample stamp within the rest (a channel that
  never delivers is wired wrong or not at all).
- **The force reads the declared load** at rest: a dead weight hanging still pulls
  m g on an in-line load cell (no acceleration), within `FORCE_TOLERANCE` of it or
  `safety.tare_tolerance_n`, whichever is larger; the opposite sign is an inverted
  load cell (`pamd.loop.safety.load_check`, the rule every declared load is checked by).
- **The pressure rises when the valve opens**: over the steps, the measured pressure's
  change per change of the valve command (least squares through 0) lies between
  `PRESSURE_GAIN` bounds (a regulator follows its setpoint; the opposite sign is an
  inverted sensor or valve, a gain near 0 no air or a wrong scale).
- **The length shortens as the pressure rises**: the length's change per measured
  pressure change is negative, and within `LENGTH_RATIO` of what the force model
  predicts for the declared load (static equilibrium before and after the step;
  friction makes a small step move less, so the bounds are wide).
- **Every signal changes** over the run (a value that never changes while the rig
  moves is a dead channel or a constant).
"""

from __future__ import annotations

from pamd.client.commission.measure import Measurements, Step
from pamd.client.commission.moves import CommissionRefused, Moves
from pamd.config import LoadedConfig
from pamd.loop.safety.load_check import check_load, inverted
from pamd.muscle_type import GRAVITY_M_S2, equilibrium_contraction

FORCE_TOLERANCE = 0.1
PRESSURE_GAIN = (0.5, 2.0)
LENGTH_RATIO = (0.2, 5.0)
#: a length that moved less than this over every move did not move, mm
LENGTH_STILL_MM = 0.05


def check_rest(cfg: LoadedConfig, meas: Measurements) -> list[str]:
    """What held, as lines for the report (a failure raises)."""
    held = [f"{st.name} updates (every {1000 * st.period_s:.1f} ms at rest)"
            for st in meas.signals.values()]
    for st in meas.signals.values():
        if st.samples < 2:
            raise CommissionRefused(
                f"{st.name} delivered {'no' if st.samples == 0 else 'only one'} sample at "
                "rest: the channel never updates; check its driver and channel in the "
                "config, the wiring and the device (is it powered, does it answer?)")
    for m in cfg.rig.muscles:
        st = meas.signals[f"{m.name}.force"]
        weight = m.load_kg * GRAVITY_M_S2
        # a gain check: tighter than the start-up's (pamd.loop.safety.load_check), whose
        # tolerance allows for friction a commissioning rest does not need
        tol = max(FORCE_TOLERANCE * weight, cfg.rig.safety.tare_tolerance_n)
        f = st.rest_mean
        wrong = check_load(m.name, f, m.load_kg, tol)
        if wrong is not None:
            raise CommissionRefused(wrong.text() + ("" if inverted(wrong) else (
                f": check muscles[{m.name}].signals.force.gain/offset (N per raw unit), the "
                "load cell (`pamd tare` with no load) and load_kg")))
        held.append(f"{m.name}.force reads {f:.1f} N at rest; the declared {m.load_kg:g} kg "
                    f"pulls {weight:.1f} N (tolerance {tol:.0f} N)")
    return held


def check_step(cfg: LoadedConfig, mv: Moves, steps: list[Step], phase: str,
               signs_only: bool = False) -> list[str]:
    """What held, as lines for the report (a failure raises). The signs over every
    move (the ramps to the levels too); the scales over the small steps (up, down)
    only, near the level the force model is evaluated at. `signs_only`: a phase cut
    short (its last move partial)."""
    m = mv.muscle
    if not steps:
        raise CommissionRefused(f"{m}: no step of the valve command was found in the "
                                f"{phase} (did the plan run?)")
    shown = "; ".join(f"{s.name}: command {s.command_change_bar:+.2f} bar, pressure "
                      f"{s.pressure_change_bar:+.2f} bar, length {s.length_change_mm:+.2f} mm"
                      for s in steps)
    _check_pressure_sign(m, steps, shown)
    _check_length_sign(m, steps, shown)
    small = [s for s in steps if s.name.startswith(("up", "down"))]
    if signs_only or not small:
        return [f"{m} ({phase}, signs): the pressure rose with the valve command, the length "
                "shortened"]
    gain = _check_pressure_scale(m, small, shown)
    return [f"{m} ({phase}): the pressure rose {gain:.2f} bar per bar of valve command "
            f"(expected {PRESSURE_GAIN[0]:g} to {PRESSURE_GAIN[1]:g})",
            _check_length_scale(cfg, mv, small, shown, phase)]


def _check_pressure_sign(m: str, steps: list[Step], shown: str) -> None:
    """The valve command moved, and the pressure followed it, the right way round."""
    sc = sum(s.command_change_bar ** 2 for s in steps)
    if not sc > 0.0:
        raise CommissionRefused(f"{m}: the valve command never changed ({shown}): the "
                                "plan did not move the rig")
    gain = sum(s.pressure_change_bar * s.command_change_bar for s in steps) / sc
    if gain <= -PRESSURE_GAIN[0]:
        raise CommissionRefused(
            f"{m}: the pressure fell when the valve opened ({shown}): a sign is inverted; "
            f"check the sign of muscles[{m}].signals.pressure.gain, the valve's scaling "
            f"(signals.valve gain, raw_min/raw_max) and their wiring")
    if gain < PRESSURE_GAIN[0]:
        raise CommissionRefused(
            f"{m}: the pressure did not follow the valve ({gain:.2f} bar per bar of command; "
            f"{shown}): check the air supply, the valve's wiring and scaling (signals.valve) "
            "and the pressure sensor's channel and scaling (signals.pressure)")


def _check_length_sign(m: str, steps: list[Step], shown: str) -> None:
    """The length moved, and shortened as the pressure rose."""
    dp = sum(s.pressure_change_bar ** 2 for s in steps)
    per_bar = sum(s.length_change_mm * s.pressure_change_bar for s in steps) / dp if dp else 0.0
    moved = max(abs(s.length_change_mm) for s in steps)
    if moved < LENGTH_STILL_MM:
        raise CommissionRefused(
            f"{m}: the length did not move while the pressure changed ({shown}): a dead or "
            f"stuck encoder, or the wrong channel; check muscles[{m}].signals.length")
    if per_bar >= 0.0:
        raise CommissionRefused(
            f"{m}: the length grew as the pressure rose ({shown}); a muscle shortens when "
            f"its pressure rises: check the sign of muscles[{m}].signals.length.gain and "
            "the encoder's counting direction")


def _check_pressure_scale(m: str, steps: list[Step], shown: str) -> float:
    """The pressure's change per change of the valve command over the small steps,
    within PRESSURE_GAIN (returned)."""
    sc = sum(s.command_change_bar ** 2 for s in steps)
    gain = sum(s.pressure_change_bar * s.command_change_bar for s in steps) / sc
    lo, hi = PRESSURE_GAIN
    if not lo <= gain <= hi:
        raise CommissionRefused(
            f"{m}: the pressure changed {gain:.2f} bar per bar of valve command ({shown}), "
            f"not {lo:g} to {hi:g}: check the supply, the valve's scaling (signals.valve "
            f"gain, raw_min/raw_max) and the pressure sensor's (signals.pressure.gain/offset)")
    return gain


def _check_length_scale(cfg: LoadedConfig, mv: Moves, steps: list[Step], shown: str,
                        phase: str) -> str:
    """The length's change per bar over the small steps, within LENGTH_RATIO of what the
    force model predicts for the declared load near the first level; the line that
    says so."""
    m = mv.muscle
    mcfg = cfg.muscle(m)
    model = cfg.muscle_type(m).force_model(mcfg.force_model)
    dp = sum(s.pressure_change_bar ** 2 for s in steps)
    per_bar = sum(s.length_change_mm * s.pressure_change_bar for s in steps) / dp
    level = mv.levels_bar[0]
    x0 = equilibrium_contraction(model, level, mcfg.load_kg)
    x1 = equilibrium_contraction(model, level + 1.0, mcfg.load_kg)
    expected = -mcfg.nominal_length_mm * (x1 - x0)  # mm per bar near the first level
    ratio = per_bar / expected
    lo, hi = LENGTH_RATIO
    if not lo <= ratio <= hi:
        raise CommissionRefused(
            f"{m}: the length moved {per_bar:.2f} mm per bar where the force model with "
            f"{mcfg.load_kg:g} kg expects about {expected:.2f} mm per bar ({shown}): check "
            f"muscles[{m}].signals.length.gain (mm per count), nominal_length_mm and load_kg")
    return (f"{m} ({phase}): the length moved {per_bar:+.2f} mm per bar (the force model "
            f"with {mcfg.load_kg:g} kg: {expected:+.2f}; expected share {lo:g} to {hi:g})")


def check_changes(meas: Measurements) -> list[str]:
    for st in meas.signals.values():
        if st.samples and not st.changes:
            raise CommissionRefused(
                f"{st.name} never changed in {st.samples} samples, at rest and while the "
                "muscle moved: a dead channel or a constant; check its channel in the config, "
                "the wiring and the sensor's supply")
    return [f"every signal changed over the run ({len(meas.signals)} signals)"]

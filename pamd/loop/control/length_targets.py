"""Length targets and length profiles for the length modes, checked before anything
moves: inside the contraction soft limits, reachable with the hanging load between
0 bar and the pressure limit, and within the length rate limit.

Role: the checks the `profile` / `setpoint` command handlers (loop thread, not the
tick) and `pamd run --profile` (config only, before the rig starts) run.
"""

from __future__ import annotations

from dataclasses import replace

from pamd.config.loader import LoadedConfig
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.muscle_type import equilibrium_contraction
from pamd.profiles import Harmonic, Profile, ProfileSpec, shape_of
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused

#: Length targets keep this far (contraction) inside what the load lets the muscle reach.
REACH_MARGIN = 0.005


def check_contraction(env: MuscleEnvelope, what: str, *values: float) -> None:
    lo, hi = env.contraction_bounds()
    for v in values:
        if not lo - 1e-12 <= v <= hi + 1e-12:
            raise CommandRefused(
                f"{env.name}: {what} {100 * v:.2f} % contraction is outside the allowed "
                f"{100 * lo:.2f} % to {100 * hi:.2f} % (soft limits: "
                f"{100 * env.max_contraction:.1f} % contraction, "
                f"{100 * env.max_pretension:.1f} % stretch, less the soft band)")


def check_reachable(env: MuscleEnvelope, load_kg: float, *values: float,
                    margin: float = REACH_MARGIN) -> None:
    """Refuse length targets the hanging load does not let the muscle reach between 0 bar
    and its pressure limit (by the static force model, with a margin)."""
    fm, load, max_p = env.force_model, load_kg, env.max_pressure_bar
    x_hi = equilibrium_contraction(fm, max_p, load)
    x_lo = equilibrium_contraction(fm, 0.0, load)
    for v in values:
        if v > x_hi - margin:
            raise CommandRefused(
                f"{env.name}: with {load:g} kg the muscle reaches about {100 * x_hi:.1f} % "
                f"contraction at {max_p:g} bar (static force model); {100 * v:.1f} % needs "
                f"at most {100 * (x_hi - margin):.1f} %")
        if v < x_lo + margin:
            raise CommandRefused(
                f"{env.name}: with {load:g} kg the muscle hangs at about {100 * x_lo:.1f} % "
                f"contraction at 0 bar; {100 * v:.1f} % would need pushing (at least "
                f"{100 * (x_lo + margin):.1f} %)")


def _what_would_pass(spec: ProfileSpec, rate: float, max_rate: float) -> str:
    """The change that brings a too fast profile within the rate limit: for a shape whose
    steepest slope grows with its frequency (sine, triangle), the highest frequency that
    passes over this span; else the span or the shape's own rate."""
    if spec.freq_hz:
        half = replace(spec, freq_hz=spec.freq_hz / 2).shape_max_rate(max_rate)
        if abs(2.0 * half - rate) <= 1e-9 * rate:  # the slope is proportional to freq_hz
            return (f"at most {spec.freq_hz * max_rate / rate:.3g} Hz passes over this span; "
                    "lower freq_hz or the span")
    return "lower freq_hz or the span"


def length_profile(env: MuscleEnvelope, load_kg: float, target_length_mm: float, now: float,
                   shape_name: str, *, min_contraction: float | None,
                   max_contraction: float | None, to_contraction: float | None,
                   freq_hz: float, cycles: int | None, rate_per_s: float | None,
                   rise_s: float | None, duration_s: float | None,
                   lead_in_per_s: float | None,
                   harmonics: tuple[tuple[int, float], ...] | None = None,
                   period_s: float = 1e-3) -> Profile:
    """A length profile for the muscle of `env` with `load_kg` hanging, starting from
    its present `target_length_mm`, in contraction (fraction) units, checked against
    the contraction limits, the length rate limit and what a tick of the loop's
    `period_s` affords (the harmonics) before anything moves."""
    max_rate = env.max_length_rate_per_s
    shape = shape_of(shape_name)  # unknown shapes refused, naming the known ones
    # every number physical, one cycle and the whole run within MAX_PROFILE_S, as for a
    # pressure profile (a length profile at freq_hz 1e-300 was accepted)
    numbers = ProfileSpec(shape_name=shape_name, min_bar=min_contraction or 0.0,
                          max_bar=max_contraction or 0.0, freq_hz=freq_hz, cycles=cycles,
                          to_bar=to_contraction, rate_bar_per_s=rate_per_s, rise_s=rise_s,
                          duration_s=duration_s, lead_in_bar_per_s=lead_in_per_s or 1.0,
                          harmonics=harmonics)
    numbers.check_values()
    numbers.check_duration()
    if shape.periodic:
        if min_contraction is None or max_contraction is None:
            raise CommandRefused(f"{shape_name} length profile: give min_contraction and "
                                 "max_contraction (fractions, e.g. 0.05 and 0.20)")
        if not max_contraction > min_contraction:
            raise CommandRefused(f"{shape_name} length profile: max_contraction "
                                 f"({max_contraction}) must exceed min_contraction "
                                 f"({min_contraction})")
        check_contraction(env, f"{shape_name} profile spans to", min_contraction, max_contraction)
    else:
        if to_contraction is None:
            raise CommandRefused(f"{shape_name} length profile: give to_contraction")
        check_contraction(env, f"{shape_name} profile target", to_contraction)
    check_reachable(env, load_kg, *(v for v in (min_contraction, max_contraction,
                                                to_contraction) if v is not None))
    lead = lead_in_per_s if lead_in_per_s is not None else 0.5 * max_rate
    if not 0 < lead <= max_rate:
        raise CommandRefused(f"lead-in rate must be in (0, {max_rate:.3g}] contraction/s "
                             f"({env.length_rate_origin})")
    spec = ProfileSpec(shape_name=shape_name,
                       min_bar=min_contraction if min_contraction is not None else 0.0,
                       max_bar=max_contraction if max_contraction is not None else 0.0,
                       freq_hz=freq_hz, cycles=cycles, to_bar=to_contraction,
                       rate_bar_per_s=rate_per_s, rise_s=rise_s, duration_s=duration_s,
                       lead_in_bar_per_s=lead, harmonics=harmonics)
    spec.check_reads()  # a parameter the shape would ignore (as for pressure profiles)
    # ProfileSpec is unit-free arithmetic; here its "bar" fields hold contraction.
    if isinstance(spec.shape, Harmonic):  # the sum of harmonics within limits and reach
        c_lo, c_hi = env.contraction_bounds()
        fm, p_hi = env.force_model, env.max_pressure_bar
        r_lo = equilibrium_contraction(fm, 0.0, load_kg) + REACH_MARGIN
        r_hi = equilibrium_contraction(fm, p_hi, load_kg) - REACH_MARGIN
        spec.shape.check_params(spec)
        spec.shape.check_cost(spec, period_s)
        spec.shape.check_harmonics(
            spec, max(c_lo, r_lo), min(c_hi, r_hi), max_rate, "% contraction", 100.0,
            f" (soft limits, reach with {load_kg:g} kg, {env.length_rate_origin})")
    rate = spec.shape_max_rate(max_rate)
    if rate > max_rate * (1 + 1e-9):
        raise CommandRefused(
            f"{shape_name} length profile needs {rate:.3g} contraction/s "
            f"({rate * env.nominal_length_mm:.3g} mm/s) but the limit is {max_rate:.3g}/s "
            f"({env.length_rate_origin}); {_what_would_pass(spec, rate, max_rate)}")
    if cycles is not None and cycles < 1:
        raise CommandRefused("cycles must be at least 1")
    return Profile(spec, now, env.contraction(target_length_mm), max_rate)


def check_length_profile_config(cfg: LoadedConfig, muscle: str,
                                payload: JsonObject) -> None:
    """`length_profile`'s checks from the config alone (limits, load, rate), for a
    profile asked for before the rig starts (`pamd run --mode position --profile`):
    the muscle at its nominal length with its configured load."""
    env = MuscleEnvelope.from_config(cfg, muscle)
    length_profile(env, cfg.muscle(muscle).load_kg, env.nominal_length_mm, 0.0,
                   str(payload.get("shape", payload.get("kind", "sine"))),
                   min_contraction=payload.get("min_contraction"),
                   max_contraction=payload.get("max_contraction"),
                   to_contraction=payload.get("to_contraction"),
                   freq_hz=payload.get("freq_hz", 0.05), cycles=payload.get("cycles"),
                   rate_per_s=payload.get("rate_per_s"), rise_s=payload.get("rise_s"),
                   duration_s=payload.get("duration_s"),
                   lead_in_per_s=payload.get("lead_in_per_s"),
                   harmonics=payload.get("harmonics"), period_s=cfg.period_s)

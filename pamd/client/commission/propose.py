"""The config's thresholds beside what was measured, their margins, and the thresholds
the measurements give (each with its rule, printed with it).

- **signal timeout** (`muscles[].signals.<s>.timeout_s`; the present one is the
  effective age limit, `pamd.config.loader.effective_timeout_s`) against the worst age
  the loop saw: proposed max(`TIMEOUT_FACTOR` x the worst age, the worst age +
  `safety.latency_margin_s`), rounded up to 5 ms. Twice the worst age leaves a healthy
  sensor a whole update gap late before it faults; the latency margin is the host's
  allowance (a busy PC, a bus transaction) that a run on the virtual clock cannot see.
  A timeout above the safe ceiling (1 s) cannot be proposed: refused.
- **jump allowances** (`safety.plausibility.pressure_jump_bar`, `length_jump_mm`)
  against the largest change between two samples beyond the rate the check allows
  over their stamps: proposed max(`NOISE_SIGMAS` x the noise at rest, `QUANTA` x the
  quantisation step, twice the largest excess), two significant digits up: a noise
  excursion between two independent samples beyond 10 sd (7 sd of their difference)
  is not expected in the life of a rig.
- **frozen time** (`safety.plausibility.frozen_s`) against the worst update gap of the
  pressure and force: at least `FROZEN_GAPS` gaps (one identical value sampled three
  times), else proposed at that.
- **stall timeout** (`loop.stall_timeout_s`) against the loop's worst wake-up lateness
  (the real clock only): proposed max(`STALL_FACTOR` x it, `STALL_PERIODS` periods),
  rounded up to 5 ms, and never below the present one: a run of a minute does not see
  the rare worst case of a busy PC, so it only raises a timeout the rig passed.
A present threshold the healthy rig passed (the measured figure beyond it) is
marked FIRES: it faults (or warns) on this rig as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pamd.client.commission.measure import Measurements
from pamd.config import LoadedConfig
from pamd.config.loader import effective_timeout_s

TIMEOUT_FACTOR = 2.0
TIMEOUT_CEILING_S = 1.0
NOISE_SIGMAS = 10.0
QUANTA = 4.0
FROZEN_GAPS = 2.0
STALL_FACTOR = 4.0
STALL_PERIODS = 5.0

KeyPath = tuple[str, ...]


@dataclass(frozen=True)
class Threshold:
    key: KeyPath  # where it lives in the config
    unit: str
    present: float
    measured: float
    measured_what: str
    proposed: float | None  # None: nothing measured to propose from
    rule: str

    @property
    def name(self) -> str:
        return ".".join(self.key).replace(".[", "[")

    @property
    def margin(self) -> float:
        return self.present - self.measured

    @property
    def fires(self) -> bool:
        return math.isfinite(self.measured) and self.measured > self.present

    @property
    def changed(self) -> bool:
        return self.proposed is not None and not math.isclose(self.proposed, self.present,
                                                              rel_tol=1e-9)

    def as_dict(self) -> dict[str, object]:
        def clean(v: float | None) -> float | None:
            return v if v is not None and math.isfinite(v) else None
        return {"key": self.name, "unit": self.unit, "present": self.present,
                "measured": clean(self.measured), "measured_what": self.measured_what,
                "margin": clean(self.margin), "fires": self.fires,
                "proposed": clean(self.proposed), "rule": self.rule}


def up_to(x: float, step: float) -> float:
    return round(math.ceil(x / step - 1e-9) * step, 6)


def two_digits_up(x: float) -> float:
    if not x > 0.0:
        return 0.0
    e = math.floor(math.log10(x)) - 1
    return float(f"{math.ceil(x / 10.0 ** e - 1e-9) * 10.0 ** e:.3g}")


def thresholds(cfg: LoadedConfig, meas: Measurements) -> tuple[list[Threshold], list[str]]:
    """The rows of the thresholds table, and the refusals among the proposals."""
    refusals: list[str] = []
    rows = _timeout_rows(cfg, meas, refusals) + _jump_rows(cfg, meas)
    rows += [row for row in (_frozen_row(cfg, meas), _stall_row(cfg, meas)) if row is not None]
    return rows, refusals


def _timeout_rows(cfg: LoadedConfig, meas: Measurements, refusals: list[str]
                  ) -> list[Threshold]:
    """Each measured signal's timeout; a proposal above the safe ceiling is refused (the
    reason added to `refusals`)."""
    rows: list[Threshold] = []
    safety = cfg.rig.safety
    margin = safety.latency_margin_s
    for m in cfg.rig.muscles:
        for s in ("pressure", "force", "length"):
            st = meas.signals.get(f"{m.name}.{s}")
            if st is None or not math.isfinite(st.worst_age_s):
                continue
            age = st.worst_age_s
            prop = up_to(max(TIMEOUT_FACTOR * age, age + margin), 0.005)
            if prop > TIMEOUT_CEILING_S:
                refusals.append(
                    f"{st.name}: its samples were up to {1000 * age:.0f} ms old: no timeout "
                    f"under the safe ceiling ({TIMEOUT_CEILING_S:g} s) guards it; a faster "
                    "device or link is needed")
                prop = math.nan
            rows.append(Threshold(
                ("muscles", f"[{m.name}]", "signals", s, "timeout_s"), "s",
                effective_timeout_s(getattr(m.signals, s), safety), age, "worst age",
                None if math.isnan(prop) else prop,
                f"max({TIMEOUT_FACTOR:g} x worst age, worst age + safety.latency_margin_s "
                f"{margin:g} s), up to 5 ms"))
    return rows


def _jump_rows(cfg: LoadedConfig, meas: Measurements) -> list[Threshold]:
    """The pressure and length jump allowances, where a jump was measured."""
    rows: list[Threshold] = []
    pl = cfg.rig.safety.plausibility
    for s, key, present in (("pressure", "pressure_jump_bar", pl.pressure_jump_bar),
                            ("length", "length_jump_mm", pl.length_jump_mm)):
        stats = [meas.signals[f"{m.name}.{s}"] for m in cfg.rig.muscles
                 if f"{m.name}.{s}" in meas.signals]
        excess = [st.jump_excess for st in stats if math.isfinite(st.jump_excess)]
        if not excess:
            continue
        worst = max(excess)
        noise = max((st.noise for st in stats if math.isfinite(st.noise)), default=0.0)
        quantum = max((st.quantum or 0.0 for st in stats), default=0.0)
        prop = two_digits_up(max(NOISE_SIGMAS * noise, QUANTA * quantum, 2.0 * worst))
        rows.append(Threshold(
            ("safety", "plausibility", key), "bar" if s == "pressure" else "mm", present,
            max(worst, 0.0), "excess over rate", prop or None,
            f"max({NOISE_SIGMAS:g} x noise sd at rest, {QUANTA:g} x quantum, 2 x largest "
            "change beyond the rate), 2 digits up"))
    return rows


def _frozen_row(cfg: LoadedConfig, meas: Measurements) -> Threshold | None:
    """The frozen time against the worst update gap of the pressures and forces."""
    gaps = [st.worst_gap_s for st in meas.signals.values()
            if st.name.endswith((".pressure", ".force")) and math.isfinite(st.worst_gap_s)]
    if not gaps:
        return None
    pl = cfg.rig.safety.plausibility
    need = round(FROZEN_GAPS * max(gaps), 6)
    prop = up_to(need, 0.01) if pl.frozen_s < need else pl.frozen_s
    return Threshold(
        ("safety", "plausibility", "frozen_s"), "s", pl.frozen_s, need,
        f"{FROZEN_GAPS:g} x worst gap", prop,
        f"at least {FROZEN_GAPS:g} x the worst update gap (one value sampled three "
        "times), up to 10 ms")


def _stall_row(cfg: LoadedConfig, meas: Measurements) -> Threshold | None:
    """The stall timeout against the worst wake-up lateness (measured on the real clock
    only), where the loop ticked."""
    lp = meas.loop
    stall = cfg.rig.loop.stall_timeout_s
    if not lp.ticks:
        return None
    prop_s: float | None = None
    if lp.measured:
        prop_s = max(stall, up_to(max(STALL_FACTOR * lp.wake_max_s,
                                      STALL_PERIODS * cfg.period_s), 0.005))
    return Threshold(
        ("loop", "stall_timeout_s"), "s", stall, lp.wake_max_s if lp.measured else math.nan,
        "worst wake-up" if lp.measured else "not measured (virtual clock)",
        prop_s, f"max({STALL_FACTOR:g} x worst wake-up lateness, {STALL_PERIODS:g} "
        "periods), up to 5 ms, never lowered; the real clock only")

"""The commissioning report: the measured figures per signal, the signs and scaling
that held, the loop's timing, and the thresholds table (present, measured, margin,
proposed, rule); as text for the operator or one JSON object for scripts."""

from __future__ import annotations

import math

from pamd.client.commission.commissioning import Outcome
from pamd.client.commission.measure import Measurements, SignalStats, Step
from pamd.client.commission.propose import Threshold
from pamd.wire.declare.jsonsafe import JsonObject


def _ms(x: float) -> str:
    return f"{1000 * x:.1f} ms" if math.isfinite(x) else "-"


def _num(x: float | None, unit: str = "") -> str:
    if x is None or not math.isfinite(x):
        return "-"
    return f"{x:.3g}{(' ' + unit) if unit else ''}"


def _latency(steps: list[Step], name: str, which: str) -> str:
    muscle, sig = name.split(".", 1)
    if sig not in ("pressure", "length"):
        return "-"
    vals = [getattr(s, f"{sig}_latency_s") for s in steps if s.muscle == muscle]
    vals = [v for v in vals if math.isfinite(v)]
    if not vals:
        return "-"
    return f"{1000 * sum(vals) / len(vals):.0f} ms" if which == "mean" else \
        f"{1000 * max(vals):.0f} ms"


def text(config: str, rig_id: str, clock: str, out: Outcome,
         rows: list[Threshold]) -> str:
    m = out.measurements
    lines = [f"pamd commission: {config} (rig {rig_id}, {clock} clock, "
             f"{out.duration_s:.1f} s of rig time)", "", "signals (from the samples' stamps; "
             "latency: valve command -> the measurement passing 10 % of a step, mean/worst)"]
    head = (f"  {'signal':<14}{'samples':>8}  {'period':>9}  {'jitter':>8}  {'worst gap':>9}  "
            f"{'worst age':>9}  {'noise sd':>10}  {'quantum':>10}  {'latency':>14}")
    lines.append(head)
    for st in m.signals.values():
        lines.append(_signal_line(st, m))
    lines.append("")
    lines.append("signs and scaling")
    lines += [f"  ok  {c}" for c in out.checks] or ["  (not reached)"]
    lp = m.loop
    lines.append("")
    if lp.measured:
        lines.append(f"the loop: {lp.ticks} ticks, woke late p50 {_ms(lp.wake_p50_s)}, "
                     f"p99 {_ms(lp.wake_p99_s)}, worst {_ms(lp.wake_max_s)}")
    else:
        lines.append(f"the loop: {lp.ticks} ticks on the virtual clock (no wake-up jitter to "
                     "measure: commission on the real clock for it)")
    lines.append("")
    lines.append("thresholds (margin = present - measured; FIRES: the healthy rig passed it)")
    lines.append(f"  {'key':<42}{'present':>10}  {'measured':>28}  {'margin':>10}  "
                 f"{'proposed':>9}  rule")
    for r in rows:
        meas = f"{r.measured_what} {_num(r.measured)}" if math.isfinite(r.measured) \
            else r.measured_what
        flag = "  FIRES" if r.fires else ""
        prop = _num(r.proposed) if r.proposed is not None else "kept"
        if r.proposed is not None and not r.changed:
            prop = "same"
        lines.append(f"  {r.name:<42}{_num(r.present, r.unit):>10}  {meas:>28}  "
                     f"{_num(r.margin):>10}  {prop:>9}  {r.rule}{flag}")
    if out.faults:
        lines += ["", "faults during the run:"] + [f"  {f}" for f in out.faults]
    if out.refusals:
        lines += ["", "REFUSED:"] + [f"  {r}" for r in out.refusals]
    return "\n".join(lines)


def _signal_line(st: SignalStats, m: Measurements) -> str:
    quantum = "continuous" if st.quantum is None else f"{st.quantum:.3g} {st.unit}"
    lat = _latency(m.steps, st.name, "mean")
    if lat != "-":
        lat = f"{lat}/{_latency(m.steps, st.name, 'worst')}"
    return (f"  {st.name:<14}{st.samples:>8}  {_ms(st.period_s):>9}  {_ms(st.jitter_s):>8}  "
            f"{_ms(st.worst_gap_s):>9}  {_ms(st.worst_age_s):>9}  "
            f"{_num(st.noise, st.unit):>10}  {quantum:>10}  {lat:>14}")


def as_json(config: str, rig_id: str, clock: str, out: Outcome, rows: list[Threshold],
            saved: bool) -> JsonObject:
    m = out.measurements
    return {
        "config": config, "rig_id": rig_id, "clock": clock, "duration_s": out.duration_s,
        "ok": not out.refusals and not out.faults,
        "signals": {k: st.as_dict() for k, st in m.signals.items()},
        "steps": [s.as_dict() for s in m.steps],
        "loop": m.loop.as_dict(),
        "checks": list(out.checks),
        "thresholds": [r.as_dict() for r in rows],
        "refusals": list(out.refusals),
        "faults": list(out.faults),
        "saved": saved,
    }

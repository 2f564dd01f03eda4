"""What `pamd commission --measure-map` prints: the sweep, every hold on both branches,
the map's points and curves, how far it agrees with the muscle's present map over the
measured range, and what a save would write (text, or one JSON object)."""

from __future__ import annotations

from pamd.client.commission.maprun import MapOutcome
from pamd.wire.declare.jsonsafe import JsonObject


def as_json(path: str, out: MapOutcome, saved: bool) -> JsonObject:
    m = out.measured
    return {
        "config": path, "muscle": out.sweep.muscle, "hold_s": out.sweep.hold_s,
        "loads": [{"load_kg": ls.load_kg, "levels_bar": list(ls.levels_bar),
                   "below_bar": ls.below_bar, "above_bar": ls.above_bar}
                  for ls in out.sweep.loads],
        "skipped": list(out.sweep.skipped),
        "holds": [dict(h.__dict__) for h in m.holds],
        "points": [dict(q.__dict__) for q in m.points],
        "curves_bar": list(m.curves),
        "unused": list(m.unused),
        "comparison": None if out.comparison is None else out.comparison.as_dict(),
        "present": out.present,
        "rows": len(out.rows), "measured_rows": sum(r.measured for r in out.rows),
        "problems": list(out.problems), "refusals": list(out.refusals),
        "faults": list(out.faults), "saved": saved,
    }


def text(path: str, out: MapOutcome) -> str:
    m = out.measured
    lines = [f"pamd commission --measure-map: {path}, muscle {out.sweep.muscle}", ""]
    lines.append("the map: at each pressure level, the contraction each hanging load "
                 "settles at, midway")
    lines.append("between the rising and the falling branch, at the load cell's force; "
                 "one point per load")
    lines.append(f"holds (each {out.sweep.hold_s:g} s; branch +1 rising, -1 falling):")
    lines.append("  load kg   level bar  branch   pressure bar  contraction %   force N  "
                 "note")
    for h in m.holds:
        lines.append(f"  {h.load_kg:7g}  {h.level_bar:9g}  {h.branch:+6d}  "
                     f"{h.pressure_bar:13.3f}  {100 * h.contraction:13.2f}  "
                     f"{h.force_n:8.1f}  {h.problem}")
    lines.append("")
    lines.append("curves (level: load kg -> contraction %, loop half-width %):")
    for level, qs in m.curves.items():
        pts = ", ".join(f"{q.load_kg:g} -> {100 * q.contraction:.2f} "
                        f"(+-{100 * q.half_width:.2f})" for q in qs)
        lines.append(f"  {level:g} bar: {pts}")
    for note in [*out.sweep.skipped, *m.unused]:
        lines.append(f"  not mapped: {note}")
    c = out.comparison
    if c is not None:
        lines += ["", f"against {out.present}, over the measured range:",
                  f"  at the {c.points} points: max {100 * c.points_max:.1f} %, "
                  f"rms {100 * c.points_rms:.1f} % of its force",
                  f"  along each curve's measured span: max {100 * c.span_max:.1f} %, "
                  f"rms {100 * c.span_rms:.1f} % (worst: {c.worst})"]
    if out.rows:
        lines.append(f"the map completed to the limits: {len(out.rows)} rows, "
                     f"{sum(r.measured for r in out.rows)} on the measured spans")
    for what, items in (("problem", out.problems), ("refused", out.refusals),
                        ("fault", out.faults)):
        lines += [f"{what}: {item}" for item in items]
    return "\n".join(lines)

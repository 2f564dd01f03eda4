"""`pamd check-config FILE`: validate a rig config and say what it describes."""

from __future__ import annotations

import argparse

from pamd.config import load_config
from pamd.config.gains import loop_margins
from pamd.loop.control.feedforward import load_models
from pamd.loop.safety.envelope import MuscleEnvelope


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "check-config", help="validate a rig config file",
        description="Validate a rig config: syntax, unknown keys, types, units and bounds, "
        "drivers and channels, limits against the muscle's ratings, each model_file against its "
        "muscle, each loop's gains against the muscle's plant (the closed loop's gain and "
        "phase margins, printed; docs/how-to/tune.md, 'Gains judged against stability'), "
        "timing keys against what they count. Exits 0 if valid, 2 "
        "with every problem (file:line: key: expected ..., found ...) if not.")
    p.add_argument("file", help="the YAML config file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg = load_config(args.file)
    models = load_models(cfg)  # as the daemon loads them: a model that does not fit is refused
    rig = cfg.rig
    print(f"{args.file}: valid. rig {rig.rig_id!r}, {rig.loop.rate_hz:g} Hz "
          f"({rig.loop.clock} clock), drivers: "
          f"{', '.join(f'{d.name} ({d.type})' for d in rig.drivers)}")
    for i, m in enumerate(rig.muscles):
        lim = cfg.limits[m.name]
        print(f"  muscle {m.name}: {m.type}, {m.nominal_length_mm:g} mm, load {m.load_kg:g} kg;"
              f" limits {lim.max_pressure_bar:g} bar, {100 * lim.max_contraction:g} % "
              f"contraction, {100 * lim.max_pretension:g} % stretch"
              + (f"; model {models[m.name].path}" if m.name in models else ""))
        t = cfg.muscle_type(m.name)
        print(f"    type {t.name}: rated {t.max_pressure_bar:g} bar, "
              f"{100 * t.max_contraction:g} % contraction, {100 * t.max_pretension:g} % "
              f"stretch, {t.max_load_kg:g} kg, {t.theoretical_force_n:g} N; {t.source}")
        if rig.control.position.max_rate_per_s is None:
            print(f"    length rate limit (control.position.max_rate_per_s: null): "
                  f"{MuscleEnvelope.derived_length_rate(cfg, m.name).explain()}")
        else:
            print(f"    length rate limit: {rig.control.position.max_rate_per_s:g}/s "
                  "(control.position.max_rate_per_s)")
        for loop, judged, plant in loop_margins(rig, i):
            print(f"    {loop} loop: {judged.margins.text()}{judged.note()}; plant {plant}")
        if m.actuation == "onoff":
            o = m.onoff
            print(f"    on/off valves: PWM {1e3 * o.pwm_period_s:g} ms, fill "
                  f"{o.fill_rate_bar_per_s:g} bar/s, vent {o.vent_rate_bar_per_s:g} bar/s, "
                  f"response {1e3 * o.response_s:g} ms, dead band {o.dead_band_bar:g} bar")
    return 0

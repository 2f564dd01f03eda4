"""`pamd commission --measure-map`: the sweep chosen and checked, run, reported, and with
--save written as the muscle's map (`muscles[].type: custom`) through the config save
path (`pamd.client.tune.save`, which writes the map's files first)."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys

from pamd.client.commission.mapfit import branches_csv, map_csv
from pamd.client.commission.mapreport import as_json, text
from pamd.client.commission.maprun import MapOutcome, measure_map
from pamd.client.commission.mapsweep import MapSweep, choose_sweep
from pamd.client.commission.moves import CommissionRefused
from pamd.client.tune.save import save_values
from pamd.client.tune.yamledit import KeyPath, Value
from pamd.config import LoadedConfig
from pamd.muscle_type.custom import NAME as CUSTOM


def run_map(args: argparse.Namespace, path: str, cfg: LoadedConfig) -> int:
    muscle = _map_muscle(args, [m.name for m in cfg.rig.muscles])
    loads = _numbers(args.map_loads, "--map-loads", "loads in kg", "25,50,100")
    levels = _numbers(args.map_levels, "--map-levels", "pressures in bar", "1,2,3,4")
    sweep = choose_sweep(cfg, muscle, loads, levels, args.map_hold_s, args.map_rate)
    _announce(sweep)
    out = measure_map(cfg, sweep, _progress, _ask, args.state_dir)
    saved = False
    if args.save and out.usable:
        with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
            save_map(path, cfg, out)
        saved = True
    _report(args, path, out, saved)
    if out.refusals or (args.save and not saved):
        return CommissionRefused.exit_code
    return 1 if out.faults else 0


def _map_muscle(args: argparse.Namespace, names: list[str]) -> str:
    """The one muscle to measure: --muscle, or the rig's only one."""
    if args.muscle and len(args.muscle) > 1:
        raise CommissionRefused("--measure-map measures one muscle at a time: give one "
                                "--muscle")
    if not args.muscle and len(names) > 1:
        raise CommissionRefused(f"--measure-map measures one muscle: name it (--muscle; this "
                                f"rig has {', '.join(names)})")
    return str(args.muscle[0]) if args.muscle else names[0]


def _announce(sweep: MapSweep) -> None:
    """Each load's levels and turning points, and what will not be measured (stderr)."""
    for ls in sweep.loads:
        _progress(f"{sweep.muscle}: {ls.load_kg:g} kg at "
                  f"{', '.join(f'{p:g}' for p in ls.levels_bar)}"
                  f" bar, rising from {ls.below_bar if ls.below_bar is not None else '-'}, "
                  f"turning at {ls.above_bar if ls.above_bar is not None else '-'}")
    for note in sweep.skipped:
        _progress(f"not measured: {note}")


def _report(args: argparse.Namespace, path: str, out: MapOutcome, saved: bool) -> None:
    """The report, as text (with what was or was not written) or as JSON."""
    if args.json:
        print(json.dumps(as_json(path, out, saved), indent=2))
        return
    print(text(path, out))
    if args.save and not saved:
        print("nothing saved: the run was refused or faulted, or the map is not usable")
    elif not args.save:
        print("nothing written (--save writes the map and makes it the muscle's)")


def save_map(path: str, cfg: LoadedConfig, out: MapOutcome) -> None:
    """The map and its branches beside the config, and the muscle made `custom` with it
    (its present type's ratings, where it was a datasheet type)."""
    muscle = out.sweep.muscle
    stem = os.path.splitext(os.path.basename(path))[0]
    name = f"{stem}-{muscle}-map.csv"
    where = os.path.dirname(os.path.abspath(path))
    t, m = cfg.muscle_type(muscle), cfg.muscle(muscle)
    files = {os.path.join(where, name): map_csv(out.rows, muscle, f"{len(out.sweep.loads)} "
                                                "loads"),
             os.path.join(where, f"{stem}-{muscle}-map-branches.csv"):
                 branches_csv(out.measured.holds, muscle)}
    base: KeyPath = ("muscles", f"[{muscle}]")
    values: dict[KeyPath, Value] = {base + ("type",): CUSTOM,
                                    base + ("custom", "map_file"): name}
    if t.name != CUSTOM:
        print(f"the custom muscle's ratings are the {t.name}'s ({t.source}): review them")
        for key in ("max_pressure_bar", "max_contraction", "max_pretension", "max_load_kg",
                    "theoretical_force_n", "inner_diameter_mm"):
            values[base + ("custom", key)] = float(getattr(t, key))
    if m.force_model != "map":
        values[base + ("force_model",)] = "map"
    save_values(path, values, "measured map", "pamd commission --measure-map", "map measured",
                files)


def _numbers(value: str | None, option: str, what: str, example: str
             ) -> tuple[float, ...] | None:
    if not value:
        return None
    try:
        return tuple(float(v) for v in value.split(","))
    except ValueError:
        raise CommissionRefused(f"{option} {value!r}: give {what} separated by commas, e.g. "
                                f"{example}") from None


def _progress(line: str) -> None:
    print(f"pamd commission: {line}", file=sys.stderr, flush=True)


def _ask(prompt: str) -> bool:
    """An operator's action (a load to hang): Enter once done; no terminal: stop."""
    msg = f"\n>>> {prompt}. Press Enter when done (Ctrl-C stops): "
    if not sys.stdin.isatty() and not os.environ.get("PAMD_OPERATOR_STDIN"):
        print(msg + "(no operator terminal: stopping)", file=sys.stderr)
        return False
    try:
        input(msg)
    except (EOFError, KeyboardInterrupt):
        return False
    return True

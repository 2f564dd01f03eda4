"""`pamd commission`: measure a rig's signals and timing at rest and in small, slow
moves inside its limits, check its sensors' signs and scaling, and propose the sensor
and timing thresholds of its config from what was measured; `--save` writes them."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys

from pamd.client.cli.commission_map import run_map
from pamd.client.commission.commission_report import as_json, text
from pamd.client.commission.commissioning import Outcome, commission
from pamd.client.commission.mapsweep import RATE_BAR_PER_S
from pamd.client.commission.moves import MAX_STEP_BAR, CommissionRefused, Moves, choose
from pamd.client.commission.propose import Threshold, thresholds
from pamd.client.tune.ident_run import parse_levels
from pamd.client.tune.save import save_values
from pamd.config import LoadedConfig, load_config
from pamd.config.loader import builtin_config_path

DESCRIPTION = f"""\
Bring up a rig: measure what its sensors and its loop really do, check that each
sensor reads the right way round, and set the config's thresholds from measurements
instead of the simulated rig's defaults.

What it does to the rig (any config `pamd run` accepts; its own clock, or --clock):
  1. rest (--rest-s, default 10 s): nothing moves, the rig holds the pressure it
     found. Every signal must deliver samples; the force must read the declared load
     (a dead weight hanging still pulls m g).
  2. first step, per muscle (--muscle, default all): a ramp at half the slew limit to
     the lower level, a step up and back down, each held --hold-s (default 2 s). The
     pressure must rise when the valve opens (0.5 to 2 bar per bar of command) and the
     length must shorten as the pressure rises (within a factor 5 of the force model).
     A wrong sign or scale stops the run here, saying which signal and what to check.
  3. the same at the upper level, then back to the lower one.
The levels lie a quarter and a half of the way from the muscle's safe pressure (with
its declared load) to its pressure limit, the step is 5 % of that span (at most
{MAX_STEP_BAR:g} bar; --levels, --step-bar to choose). A level below the safe pressure
or a level + step above the pressure limit is refused before anything opens, and every
move goes through the daemon's limits like any command: nothing moves outside them.
The rig must be free: another daemon on it is refused naming it (exit 8).

What it measures, per signal from its samples' stamps: update period, jitter, worst
gap, worst age (what the timeout is compared with), noise at rest, quantisation step,
and the latency from the valve command to the measured pressure and length; the loop's
wake-up lateness (real clock). What it prints: those, the checks that held, and the
thresholds table: each present threshold (signal timeouts, plausibility jump
allowances, frozen time, loop stall timeout) beside the figure it guards against,
the margin, FIRES where the healthy rig reached it, and the proposed value with its
rule (e.g. timeout = max(2 x worst age, worst age + safety.latency_margin_s)).

What it writes: nothing, unless --save: then the proposed thresholds go into the
config file in place, after the diff is shown, comments kept (as `pamd tune --save`);
a file that cannot be edited safely gets an overrides file beside it
(CONFIG.tuned.yaml). A refused or faulted run saves nothing.

--measure-map: instead, measure the muscle's own static force map F(pressure,
contraction) on the rig (one muscle: --muscle, default the rig's only one; commission
its signals first). Under each hanging load (--map-loads, default 1/4, 1/2, 3/4 and
all of the declared load; the simulated rig hangs them itself, an operator is asked to
and presses Enter) the pressure is stepped slowly up through the levels of the
muscle's present map (--map-levels: others) and back down, each level held until the
load hangs still (--map-hold-s, default 3 s), so each level is reached on the rising
and on the falling branch of the friction loop. One load pulls with one force: it
gives one point of each pressure curve, the contraction where the muscle's force is
its weight; the map's point is midway between the two branches (friction holds the
muscle back by about as much either way), and each curve is its loads' points. The
pressure moves slowly between levels (--map-rate, default 0.1 bar/s: a few minutes of
rig time per load). Only
levels inside the limits and above each load's safe pressure are used. It prints every
hold, the curves, and how far the measured map agrees with the muscle's present map
(its datasheet's) over the measured range. --save writes the map (completed to the
limits, each row saying whether it was measured), both branches beside it, and makes
the muscle `type: custom` with that map and its present type's ratings (review them:
a custom muscle's ratings are the config's).

Exit status: 0 done, 1 the rig faulted during the run (the fault is printed), 2 bad
config, 4 refused (a wrong sign or scale, a silent or constant signal, moves outside
the limits, a threshold that cannot be proposed, a map that cannot be measured), 8 the
rig is in use."""


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "commission", help="measure a rig's signals, check their signs, propose thresholds",
        formatter_class=argparse.RawDescriptionHelpFormatter, description=DESCRIPTION,
        epilog="examples:\n"
        "  pamd commission --clock virtual                  # the built-in simulated rig\n"
        "  pamd commission rig.yaml                         # measure and propose\n"
        "  pamd commission rig.yaml --save                  # ... and write them\n"
        "  pamd commission rig.yaml --json > commission.json  # for scripts\n"
        "  pamd commission rig.yaml --muscle m1 --levels 2,3 --step-bar 0.2\n"
        "  pamd commission rig.yaml --measure-map --map-loads 25,50,100 --save")
    p.add_argument("config", nargs="?", metavar="CONFIG",
                   help="rig config (default: the built-in simulated rig)")
    p.add_argument("--clock", choices=("real", "virtual"), help="override loop.clock")
    p.add_argument("--muscle", action="append", metavar="NAME",
                   help="a muscle to move (repeatable; default: all, one after the other)")
    p.add_argument("--levels", metavar="BAR,BAR,...",
                   help="the pressures the steps start from (default: 1/4 and 1/2 of the "
                   "way from the safe pressure to the pressure limit)")
    p.add_argument("--step-bar", type=float, metavar="BAR",
                   help=f"the step (default: 5 %% of that span, at most {MAX_STEP_BAR:g})")
    p.add_argument("--rest-s", type=float, default=10.0, metavar="S",
                   help="how long the rig rests first (default 10; at least 1)")
    p.add_argument("--hold-s", type=float, default=2.0, metavar="S",
                   help="how long each level and step is held (default 2; at least 0.5)")
    p.add_argument("--state-dir", metavar="DIR",
                   help="as `pamd run --state-dir`: where the latched fault and the home/tare "
                   "datums are kept (default: the config's state_dir, else the rig's "
                   "own for a real-clock run; a virtual-clock run keeps none)")
    p.add_argument("--save", action="store_true",
                   help="write the proposed thresholds into CONFIG (after showing the diff)")
    p.add_argument("--json", action="store_true",
                   help="print the report as one JSON object (progress stays on stderr)")
    m = p.add_argument_group("the muscle's static map (--measure-map)")
    m.add_argument("--measure-map", action="store_true",
                   help="measure the muscle's own force map under hanging loads instead "
                   "(see above); --save makes it the muscle's, as type custom")
    m.add_argument("--map-loads", metavar="KG,KG,...",
                   help="the loads to hang, at least two (default: 1/4, 1/2, 3/4 and all "
                   "of the declared load); each gives one point per pressure curve")
    m.add_argument("--map-levels", metavar="BAR,BAR,...",
                   help="the pressure levels (default: the present map's curves, 0-6 bar "
                   "on a Festo DMSP)")
    m.add_argument("--map-hold-s", type=float, default=3.0, metavar="S",
                   help="how long each level is held before the still load is measured "
                   "over the last 0.5 s (default 3; at least 1)")
    m.add_argument("--map-rate", type=float, default=RATE_BAR_PER_S, metavar="BAR/S",
                   help="how fast the pressure moves between levels (default "
                   f"{RATE_BAR_PER_S:g}: slow enough that the load's momentum does not "
                   "carry it past where friction holds it, so each branch is the "
                   "friction loop's)")
    p.set_defaults(func=run)


def _progress(line: str) -> None:
    print(f"pamd commission: {line}", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    if args.save and not args.config:
        raise CommissionRefused("--save writes into the config file: name it (the built-in "
                                "simulated rig's config is part of the installed package; "
                                "copy it first: pamd commission my-sim.yaml --save)")
    path = args.config or builtin_config_path()
    cfg = load_config(path, {"loop": {"clock": args.clock}} if args.clock else None)
    if args.measure_map:
        return run_map(args, path, cfg)
    out = commission(cfg, _moves(args, cfg), _progress, args.state_dir)
    rows, refusals = thresholds(cfg, out.measurements)
    out.refusals += refusals
    saved = bool(args.save) and not (out.refusals or out.faults) and _save(args, path, rows)
    _report(args, path, cfg, out, rows, saved)
    if out.refusals:
        return CommissionRefused.exit_code
    return 1 if out.faults else 0


def _moves(args: argparse.Namespace, cfg: LoadedConfig) -> list[Moves]:
    """The moves of each muscle named (default all), each said on stderr."""
    names = args.muscle or [m.name for m in cfg.rig.muscles]
    levels = parse_levels(args.levels, CommissionRefused, "2,3.5")
    moves: list[Moves] = [choose(cfg, n, args.rest_s, args.hold_s, levels, args.step_bar)
                          for n in names]
    for mv in moves:
        _progress(f"{mv.muscle}: rest {mv.rest_s:g} s, then steps of {mv.step_bar:g} bar at "
                  f"{', '.join(f'{lv:g}' for lv in mv.levels_bar)} bar (safe pressure "
                  f"{mv.safe_bar:.2f}, limit {mv.max_bar:g} bar)")
    return moves


def _save(args: argparse.Namespace, path: str, rows: list[Threshold]) -> bool:
    """Write the thresholds that changed into the config; whether any did (what the
    save prints goes to stderr under --json)."""
    values = {r.key: r.proposed for r in rows if r.changed and r.proposed is not None}
    with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
        if values:
            save_values(path, values, "thresholds", "pamd commission", "commissioned")
            return True
        print("the present thresholds are the proposed ones: nothing to save")
    return False


def _report(args: argparse.Namespace, path: str, cfg: LoadedConfig, out: Outcome,
            rows: list[Threshold], saved: bool) -> None:
    """The report, as text (with what was or was not written) or as JSON."""
    clock = cfg.rig.loop.clock
    if args.json:
        print(json.dumps(as_json(path, cfg.rig.rig_id, clock, out, rows, saved), indent=2))
        return
    print(text(path, cfg.rig.rig_id, clock, out, rows))
    if args.save and (out.refusals or out.faults):
        print("nothing saved: the run was refused or faulted")
    elif not args.save:
        print("nothing written (--save writes the proposed thresholds into the config)")

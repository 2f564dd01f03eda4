"""`pamd tune`: identify the pressure (or position) loop on the rig from recorded
setpoint steps, and derive its gains; `--save` writes them into the config file."""

from __future__ import annotations

import argparse
import os
import sys
import time
from functools import partial

from pamd.client.tune.ident_run import (
    LOOPS,
    LoopPlan,
    TuneRefused,
    check_actuation,
    parse_levels,
    run_identification,
    with_levels,
)
from pamd.client.tune.onoff_plot import plot_onoff
from pamd.client.tune.onoff_run import check_onoff, run_onoff
from pamd.client.tune.onoff_steps import (
    LEVEL_BAR,
    StepTest,
    derived_settings,
    print_settings,
    print_test,
)
from pamd.client.tune.placement import Placement, place
from pamd.client.tune.relay_run import MAX_RELAY_BAR, mean_relay_model, print_relay, run_relay
from pamd.client.tune.save import save_values
from pamd.client.tune.step_responses import StepResponse, check_model, fit_all, mean_model
from pamd.client.tune.tune_report import (
    Present,
    plot_fits,
    present_gains,
    print_comparison,
    print_fits,
    print_gains,
    pyplot,
)
from pamd.client.tune.yamledit import KeyPath
from pamd.config import LoadedConfig, load_config
from pamd.config.loader import builtin_config_path
from pamd.loop.control.tuning import Fopdt, IdentificationError

DESCRIPTION = """\
Identify a control loop on the rig and derive its gains, like Klipper's PID_CALIBRATE.

What it does to the rig: for each muscle (--muscle, default all), it runs the daemon
with a small plan of setpoint steps (per level: a fast ramp to the level, a step up
and a step back down, each held 2 s) and records it like any collection (one MCAP
file per plan step and the plan, in --out).
  --loop pressure (default): the PID and the rate feedforward are OFF and the slew
    limit fast, so only the regulator acts; steps of 0.2 bar at 1.5, 3 and 4.5 bar.
  --loop position: the pressure loop runs on the config's present gains (tune the
    pressure loop first); steps of 0.5 bar at 2.5 and 3.5 bar, the length measured.
Every level must lie between the muscle's safe pressure and its pressure limit
(level + step); a step larger than allowed (0.5 bar pressure, 1 bar position) is
refused. How long: 6 s of rig time per level (about 20 s per muscle; a moment on
the virtual clock).

--method relay (pressure loop): instead of steps, a relay-feedback test per level
(like Klipper's PID_CALIBRATE): the setpoint held at the level, then the loop's relay
switches the regulator setpoint between level +/- --relay-bar (default 0.2, at most
--relay-max-bar, 0.5) each time the measured pressure crosses where it rested (0.02
bar hysteresis), 8 cycles. The ultimate gain and period give the FOPDT model; the
gains follow as below. An oscillation that does not establish (no crossing within
2 s) stops the run. About 1.5 s of rig time per level.

--loop onoff (muscles on on/off valves, actuation: onoff; default: every such
muscle): the step test bench/tune_onoff.py describes, through the daemon and
recorded. The setpoint goes to 3 bar (--levels: another one) with the PWM's dead band
opened to 1 bar, held 2 s; then one timed pulse of each valve at a time, inflate then
exhaust: 40 ms (the fill and vent rates), the PWM's shortest (the dead band, the
encoder's count), 300 ms (the valve speeds: the sliding mode's boundary layer and
lambda). About 5 s of rig time per muscle. It prints each pulse's pressure and length
step and fastest length change, and the settings beside the present ones; --save
writes them into muscles[].onoff. --plot FILE: one PNG of every muscle's pulses, the
measured pressure and length around each (the valve's open interval shaded, the means
before and after, the 300 ms pulses' fastest length change), to see at a glance a
pulse that moved nothing or a noisy or drifting baseline; drawn for a refused test
too. A pulse that moves no pressure (or the wrong way), 300 ms pulses that move no
length, a fault or a moved setpoint stop it (exit 2).
The pressure and position loops are a regulator's: on a muscle on on/off valves they
are refused before anything moves (name the regulator muscles of a mixed rig with
--muscle).

The rig must be free: while another daemon (pamd run, the service, a collection,
another tune) drives it, tune is refused naming that process (exit 8).

From the recording it fits a first-order-plus-dead-time model to each step, takes
their mean, and derives Skogestad's SIMC PI gains (tau_c = dead time) and, for the
pressure loop, rate_feedforward_s = dead time + lag (the gains are the rig's control
section: with several muscles, from the mean model of all their steps). It prints
them beside the present ones, with the predicted and measured step responses (--plot
FILE: a PNG).

What it writes: nothing but the recording, unless --save: then the new gains go into
the config file (control.pid.kp/ki_per_s and control.rate_feedforward_s, or
control.position.pid.kp_bar_per_mm/ki_bar_per_mm_s), with the model they came from
(control.plant, or control.position.plant: gain, lag_s, dead_time_s; the plant every
later gain is judged against, by check-config and the daemon), in place, keeping its
comments and layout, after the diff is shown. If the file cannot be edited safely, the gains go
to an overrides file beside it (CONFIG.tuned.yaml) and it says so.
Rig-wide (the control section, from the mean model) when the muscles agree; each
muscle's own gains into its muscles[].control section (the same key names) with
--per-muscle, or by itself when only some of the rig's muscles were tuned, when their
fits differ by more than 15 %, or when a muscle already has its own value of a key.

A run that leaves the safe limits, a fault, a fit that does not converge or a model
that is not physical (wrong sign, no response) stops it: the present gains are kept,
the reason printed, exit status 2."""


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "tune", help="identify the pressure or position loop on the rig and derive its gains",
        formatter_class=argparse.RawDescriptionHelpFormatter, description=DESCRIPTION,
        epilog="examples:\n"
        "  pamd tune --clock virtual                   # the built-in simulated rig\n"
        "  pamd tune --config rig.yaml --muscle m1 --plot tune.png\n"
        "  pamd tune --config rig.yaml --save          # then: --loop position --save\n"
        "  pamd tune --config rig.yaml --method relay  # relay feedback instead of steps\n"
        "  pamd tune --config onoff.yaml --loop onoff --save  # on/off valves' settings\n"
        "  pamd tune --config onoff.yaml --loop onoff --plot onoff.png  # each pulse drawn")
    p.add_argument("--config", metavar="RIG", help="rig config (default: built-in sim)")
    p.add_argument("--loop", choices=(*LOOPS, "onoff"), default="pressure",
                   help="which loop to identify (default: pressure); onoff: the step test "
                   "of on/off valves and their settings (muscles[].onoff)")
    p.add_argument("--muscle", action="append", metavar="NAME",
                   help="a muscle to identify (repeatable; default: all)")
    p.add_argument("--levels", metavar="BAR,BAR,...",
                   help="the levels the steps start from (default: 1.5,3,4.5 for the "
                   "pressure loop, 2.5,3.5 for the position loop)")
    p.add_argument("--step-bar", type=float, metavar="BAR",
                   help="the step size (default: 0.2 pressure, 0.5 position)")
    p.add_argument("--method", choices=("step", "relay"), default="step",
                   help="how the pressure loop is identified: setpoint steps (default) or "
                   "a relay-feedback oscillation")
    p.add_argument("--relay-bar", type=float, default=0.2, metavar="BAR",
                   help="--method relay: the relay's amplitude around each level "
                   "(default 0.2)")
    p.add_argument("--relay-max-bar", type=float, default=MAX_RELAY_BAR, metavar="BAR",
                   help=f"--method relay: the largest amplitude allowed (default "
                   f"{MAX_RELAY_BAR:g}; never past the safe pressure or the pressure limit)")
    p.add_argument("--clock", choices=("real", "virtual"), help="override loop.clock")
    p.add_argument("--out", metavar="DIR", help="where the recording goes (default: "
                   "runs/tune-<loop>-<time>)")
    p.add_argument("--plot", metavar="FILE", help="a PNG of the measured and predicted "
                   "step responses; --loop onoff: of each pulse's pressure and length "
                   "(needs pamd[plot]; not with --method relay)")
    p.add_argument("--save", action="store_true",
                   help="write the new gains into the config file (after showing the diff)")
    p.add_argument("--per-muscle", action="store_true",
                   help="--save: each muscle's gains into its own muscles[].control section "
                   "(automatic when only some muscles are tuned, their fits differ by more "
                   "than 15 %%, or a muscle has its own gains already)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.save and not args.config:
        raise TuneRefused("--save writes into the config file: name it with --config (the "
                          "built-in simulated rig's config is part of the installed package; "
                          "copy it first: pamd tune --config my-sim.yaml --save)")
    config_path = args.config or builtin_config_path()
    cfg = load_config(config_path)
    if args.loop == "onoff":
        return _onoff(args, cfg, config_path)
    levels = parse_levels(args.levels, TuneRefused, "1.5,3,4.5")
    lp = with_levels(LOOPS[args.loop], levels, args.step_bar)
    muscles = args.muscle or [m.name for m in cfg.rig.muscles]
    check_actuation(cfg, muscles, lp.loop)  # before anything moves
    out = args.out or os.path.join("runs", f"tune-{lp.loop}-{time.strftime('%Y%m%d-%H%M%S')}")
    if args.method == "relay":
        _check_relay(args, lp)
        models = _relay(args, config_path, lp, muscles, out)
    else:
        models = _steps(args, config_path, lp, muscles, out)
    by_muscle = {m: Present.from_model(lp.loop, model) for m, model in models.items()}
    rig_wide = Present.from_model(lp.loop, Fopdt(
        sum(m.gain for m in models.values()) / len(models),
        sum(m.tau_s for m in models.values()) / len(models),
        sum(m.dead_time_s for m in models.values()) / len(models)))
    placement = place(cfg, by_muscle, rig_wide, args.per_muscle)
    _print_placement(cfg, lp.loop, placement, by_muscle, rig_wide)
    print(f"recording: {out}")
    if not args.save:
        print("nothing written (--save writes the new gains into the config file)")
        return 0
    return save_values(config_path, placement.values)


def _check_relay(args: argparse.Namespace, lp: LoopPlan) -> None:
    """The relay test identifies the pressure loop, and draws no step responses."""
    if lp.loop != "pressure":
        raise TuneRefused("--method relay identifies the pressure loop; the position "
                          "loop is identified by steps (--method step)")
    if args.plot:
        raise TuneRefused("--plot draws step responses: it goes with --method step")


def _print_placement(cfg: LoadedConfig, loop: str, placement: Placement,
                     by_muscle: dict[str, Present], rig_wide: Present) -> None:
    """The new gains beside the present ones, where they go and why."""
    if placement.per_muscle:
        for muscle, new in by_muscle.items():
            print(f"{muscle}:")
            print_gains(loop, present_gains(cfg, loop, muscle), new)
        print(f"per muscle (muscles[].control): {placement.why}")
    else:
        print_gains(loop, present_gains(cfg, loop), rig_wide)
        print(f"rig-wide (control): {placement.why}")


def _steps(args: argparse.Namespace, config_path: str, lp: LoopPlan, muscles: list[str],
           out: str) -> dict[str, Fopdt]:
    """The step runs of each muscle, their fits printed; each muscle's mean model."""
    fits_by_muscle: dict[str, list[tuple[StepResponse, Fopdt]]] = {}
    for muscle in muscles:
        steps = run_identification(config_path, args.clock, muscle, lp,
                                   os.path.join(out, muscle), _progress)
        fits_by_muscle[muscle] = _fit(muscle, lp, steps)
    all_fits = [f for fits in fits_by_muscle.values() for f in fits]
    model = mean_model(all_fits)
    for muscle, fits in fits_by_muscle.items():
        print_fits(f"{muscle}: {lp.loop} loop ({lp.input_column} -> {lp.output_column})",
                   lp.unit, fits, mean_model(fits))
    cfg = load_config(config_path)
    print_comparison(lp, model, present_gains(cfg, lp.loop),
                     Present.from_model(lp.loop, model), all_fits)
    if args.plot:
        plot_fits(args.plot, lp, model, fits_by_muscle)
        print(f"plot: {args.plot}")
    return {m: mean_model(fits) for m, fits in fits_by_muscle.items()}


def _relay(args: argparse.Namespace, config_path: str, lp: LoopPlan, muscles: list[str],
           out: str) -> dict[str, Fopdt]:
    """The relay test of each muscle; each muscle's mean model."""
    models: dict[str, Fopdt] = {}
    for muscle in muscles:
        runs = run_relay(config_path, args.clock, muscle, lp.levels_bar, args.relay_bar,
                         args.relay_max_bar, os.path.join(out, muscle), _progress)
        models[muscle] = mean_relay_model(runs)
        print_relay(f"{muscle}: pressure loop by relay feedback (+/- {args.relay_bar:g} bar)",
                    runs, models[muscle])
    return models


def _onoff(args: argparse.Namespace, cfg: LoadedConfig, config_path: str) -> int:
    """The on/off step test of each muscle (--muscle, default every on/off muscle), its
    measurements and settings printed; --save writes them into muscles[].onoff."""
    level = _onoff_level(args)
    muscles = _onoff_muscles(args, cfg, level)
    if args.plot:
        pyplot()  # matplotlib missing: refused now, not after the runs
    out = args.out or os.path.join("runs", f"tune-onoff-{time.strftime('%Y%m%d-%H%M%S')}")
    values = _onoff_tests(args, cfg, config_path, muscles, level, out)
    print(f"recording: {out}")
    if not args.save:
        print("nothing written (--save writes the new settings into the config file)")
        return 0
    return save_values(config_path, values, what="on/off settings")


def _onoff_level(args: argparse.Namespace) -> float:
    """The one level of the on/off step test (--levels, default LEVEL_BAR); the options
    of the other loops refused."""
    for flag, given in (("--method relay", args.method == "relay"),
                        ("--step-bar", args.step_bar is not None),
                        ("--per-muscle", args.per_muscle)):
        if given:
            raise TuneRefused(f"{flag} goes with the pressure and position loops; --loop onoff "
                              "runs the on/off valves' step test (its settings are each "
                              "muscle's own, muscles[].onoff)")
    levels = parse_levels(args.levels, TuneRefused, "3")
    if levels is not None and len(levels) != 1:
        raise TuneRefused("--loop onoff runs its step test at one level: give one, e.g. "
                          "--levels 3")
    return levels[0] if levels else LEVEL_BAR


def _onoff_muscles(args: argparse.Namespace, cfg: LoadedConfig, level: float) -> list[str]:
    """The muscles to test (--muscle, default every on/off one), all checked before
    anything opens."""
    muscles: list[str] = args.muscle or [m.name for m in cfg.rig.muscles
                                         if m.actuation == "onoff"]
    if not muscles:
        raise TuneRefused("no muscle of this rig is on on/off valves (actuation: onoff): "
                          "--loop onoff tunes those; tune a regulator with --loop pressure, "
                          "then --loop position")
    for muscle in muscles:  # all of them before anything opens
        check_onoff(cfg, muscle, level)
    return muscles


def _onoff_tests(args: argparse.Namespace, cfg: LoadedConfig, config_path: str,
                 muscles: list[str], level: float, out: str) -> dict[KeyPath, float]:
    """Each muscle's step test run, printed with its settings (present and new), and
    plotted with --plot (what was measured also when a test is refused); the new
    settings by config key."""
    values: dict[KeyPath, float] = {}
    tests: dict[str, StepTest] = {}
    for muscle in muscles:
        try:
            test = run_onoff(config_path, args.clock, muscle, os.path.join(out, muscle), level,
                             _progress, partial(tests.__setitem__, muscle))
        except TuneRefused:
            if args.plot and tests:  # what was measured, the refused test's pulses too
                _plot_onoff(args.plot, tests, level)
            raise
        present = cfg.muscle(muscle).onoff
        new = derived_settings(test, present.pwm_period_s)
        print_test(f"{muscle}: on/off step test at {level:g} bar, "
                   f"{cfg.muscle(muscle).load_kg:g} kg", test)
        print_settings(muscle, {k: float(getattr(present, k)) for k in new}, new)
        values.update({("muscles", f"[{muscle}]", "onoff", k): v for k, v in new.items()})
    if args.plot:
        _plot_onoff(args.plot, tests, level)
    return values


def _plot_onoff(path: str, tests: dict[str, StepTest], level_bar: float) -> None:
    plot_onoff(path, tests, level_bar)
    print(f"plot: {path}")


def _progress(line: str) -> None:
    print(f"pamd tune: {line}", file=sys.stderr, flush=True)


def _fit(muscle: str, lp: LoopPlan, steps: list[StepResponse]) -> list[tuple[StepResponse, Fopdt]]:
    if not steps:
        raise TuneRefused(f"{muscle}: no {lp.step_bar:g} bar step of {lp.input_column} was "
                          "found in the recording; the present gains are kept")
    try:
        fits = fit_all(steps)
        check_model(lp.loop, fits, mean_model(fits))
    except IdentificationError as exc:
        raise TuneRefused(f"{muscle}: {lp.loop} loop not identified: {exc}; the present "
                          "gains are kept") from None
    return fits

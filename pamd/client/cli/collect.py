"""`pamd collect PLAN`: run an experiment plan on the rig, unattended where it can
be, with a progress bar, one recording file per step and a manifest; `--dry-run`
checks the plan and prints its timeline without moving anything."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from types import FrameType
from typing import Protocol

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.loop.experiment.manifest import Manifest, collection_name, step_records
from pamd.loop.experiment.plan import load_plan
from pamd.loop.experiment.sequencer import Sequencer, running_plan, started_plan
from pamd.loop.experiment.timeline import StepLine, format_timeline, simulated_loads, timeline
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.tick import State


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "collect", help="run an experiment plan (e.g. the 0.05 Hz sine sweep under loads)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run an experiment plan: per step, change the load (by itself on the "
        "simulated rig; otherwise the operator hangs it and confirms, and the measured "
        "force must agree), settle, run the profile, hold. One MCAP file per step and a "
        "manifest.json go to --out.\n\n"
        "Ctrl-C once: pause at the end of the present cycle, then resume or abort. "
        "Twice: abort now, to the safe state. --resume DIR continues a collection from "
        "its first unfinished step.",
        epilog="examples:\n"
        "  pamd collect config/experiments/sine-sweep.yaml --dry-run\n"
        "  pamd collect config/experiments/sine-sweep.yaml --clock virtual --out runs/sweep\n"
        "  pamd collect sweep.yaml --config rig.yaml --resume runs/sweep")
    p.add_argument("plan", help="the experiment plan (YAML)")
    p.add_argument("--config", metavar="RIG", help="rig config (default: built-in sim)")
    p.add_argument("--out", metavar="DIR", help="where files and the manifest go "
                   "(default: runs/<plan>-<time>); refused if DIR holds a collection "
                   "already (--resume DIR continues it)")
    p.add_argument("--clock", choices=("real", "virtual"), help="override loop.clock")
    p.add_argument("--dry-run", action="store_true", help="check and print the timeline only")
    p.add_argument("--resume", metavar="DIR", help="continue the collection in DIR")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    overrides: JsonObject = {}
    if args.clock:
        overrides["loop"] = {"clock": args.clock}
    cfg = load_config(args.config, overrides)
    plan = load_plan(args.plan, cfg)
    sim = simulated_loads(cfg, plan)
    lines = timeline(plan, cfg, sim)
    print(format_timeline(plan, lines))
    if args.dry_run:
        print("dry run: the plan fits the rig's limits; nothing moved")
        return 0
    if args.resume:
        manifest = Manifest.load(args.resume)
        stale = manifest.reconcile()
        if stale:  # a crash between a step's end and the manifest's write
            print(f"{args.resume}: the manifest was stale; brought in line with the step "
                  f"files: {'; '.join(stale)}")
            manifest.save()
        if manifest.plan_name != plan.name:
            raise CommandRefused(f"{args.resume} holds plan {manifest.plan_name!r}, not "
                                 f"{plan.name!r}")
        start = manifest.first_unfinished()
        if start is None:
            print(f"{args.resume}: every step is finished; nothing to resume")
            return 0
        out = args.resume
    else:
        out = args.out or os.path.join("runs", collection_name(plan))
        if os.path.exists(os.path.join(out, "manifest.json")):
            raise CommandRefused(
                f"{out} already holds a collection (its manifest.json would be overwritten): "
                f"continue it with --resume {out}, or name a new directory with --out")
        os.makedirs(out, exist_ok=True)
        manifest = Manifest.new(out, plan, args.plan, cfg)
        manifest.save()  # before anything moves: a crash leaves one to resume from
        start = 0
    print(f"collecting into {out}, from step {start + 1} ({plan.steps[start].name})")
    daemon = Daemon(cfg, note=plan.metadata.notes, recording=RecordingRequest(
        dir=out, run_name=plan.name, segments=step_records(plan, lines),
        profile={"plan": plan.name, "plan_file": os.path.abspath(args.plan)}))
    pending = daemon.start_plan(plan, args.plan, start)
    interrupts = _signals(daemon)
    daemon.start()
    outcome = "not started"
    try:
        verdict = pending.result(cfg.rig.safety.startup_timeout_s + 5.0)
        if not verdict["ok"]:
            raise CommandRefused(verdict["error"])
        outcome = _follow(daemon, lines, start, interrupts, not args.no_progress,
                          lambda done: _step_ended(manifest, done, start))
    finally:
        daemon.stop("collection ended")
        daemon.wait()
        daemon.close()
    seq = running_plan(daemon.ctrl)
    manifest.record_run(seq, daemon.result(), start)
    manifest.save()
    print(f"{outcome}; {len(seq.finished_steps) if seq else 0} step(s) finished; "
          f"manifest: {os.path.join(out, 'manifest.json')}")
    return 0 if outcome == "done" else 1


def _step_ended(manifest: Manifest, finished: list[str], start: int) -> None:
    """A step has ended: the manifest says so now (atomically), so a crash later in
    the plan loses none of it."""
    try:
        if manifest.steps_finished(finished, start):
            manifest.save()
    except OSError as exc:
        _say(f"pamd: cannot update the manifest: {exc}")


class ProgressBar(Protocol):
    """What is used of a `tqdm` bar (an optional dependency)."""

    n: float
    total: float

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None: ...
    def clear(self) -> None: ...
    def close(self) -> None: ...


def _signals(daemon: Daemon) -> dict[str, int]:
    count = {"n": 0}
    if threading.current_thread() is not threading.main_thread():
        return count

    def handler(signum: int, frame: FrameType | None) -> None:
        count["n"] += 1
        if signum == signal.SIGTERM or count["n"] >= 2:
            _say("\npamd: aborting now: ramping to the safe state")
            daemon.submit("stop")
        else:
            _say("\npamd: Ctrl-C: pausing at the end of the present cycle (Ctrl-C again "
                 "aborts now)")
            daemon.submit("pause")

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return count


def _say(text: str) -> None:
    """Acknowledge at once, from the signal handler (the bar may be mid-line)."""
    with contextlib.suppress(OSError):
        os.write(sys.stderr.fileno(), (text + "\n").encode())


def _follow(daemon: Daemon, lines: list[StepLine], start: int, interrupts: dict[str, int],
            show: bool, step_ended: Callable[[list[str]], object] | None = None) -> str:
    """Show progress and talk to the operator until the plan ends."""
    seq = started_plan(daemon.ctrl)
    total = sum(s.duration_s for s in lines[start:])
    bar = _bar(total, show)
    with _logs_above(bar):
        outcome = _follow_loop(daemon, seq, bar, interrupts, step_ended)
    if bar is not None:
        if outcome == "done":
            bar.n = bar.total
        bar.close()
    return outcome


def _logs_above(bar: ProgressBar | None) -> AbstractContextManager[object]:
    """Log lines print above the progress bar instead of through it."""
    if bar is None:
        return contextlib.nullcontext()
    from tqdm.contrib.logging import logging_redirect_tqdm

    redirect: AbstractContextManager[object] = logging_redirect_tqdm()  # tqdm is untyped
    return redirect


def _follow_loop(daemon: Daemon, seq: Sequencer, bar: ProgressBar | None,
                 interrupts: dict[str, int],
                 step_ended: Callable[[list[str]], object] | None = None) -> str:
    ctrl = daemon.ctrl
    t0 = None
    asked = ""
    saved = 0
    while daemon.alive and not seq.outcome:
        daemon.service()
        if step_ended is not None and len(seq.finished_steps) > saved:
            saved = len(seq.finished_steps)  # the manifest says so now (atomically)
            step_ended(list(seq.finished_steps))
        if t0 is None and ctrl.supervisor.state != State.STARTING:
            t0 = ctrl.now
        if bar is not None and t0 is not None:
            pr = seq.progress()
            m = seq.muscle
            show_rig_time(bar, ctrl.now - t0)
            cyc = f" cycle {pr['cycle'] + 1}/{pr['cycles']}" if pr["cycles"] else ""
            bar.set_postfix_str(f"step {pr['index'] + 1}/{pr['steps']} {pr['step']} "
                                f"{pr['phase']}{cyc} | {m.pressure_bar:4.2f} bar "
                                f"{m.length_mm:6.2f} mm", refresh=True)
        prompt = seq.awaiting_operator
        if prompt and prompt != asked:
            asked = prompt
            _ask(daemon, prompt, bar)
        if ctrl.supervisor.state == State.HOLD and interrupts["n"] == 1 and seq.phase != "pause":
            interrupts["n"] = 0
            _pause_menu(daemon, bar)
        time.sleep(0.1)
    return seq.outcome or "aborted"


def show_rig_time(bar: ProgressBar, elapsed_s: float) -> None:
    """The rig time run so far, held to the bar's own total (rounded to 0.1 s): a count
    past it makes tqdm warn "clamping frac to range [0, 1]" and show a negative ETA (a
    plan runs a little longer than its timeline says: the last tick, the settling)."""
    bar.n = max(0.0, min(bar.total, elapsed_s))


def _ask(daemon: Daemon, prompt: str, bar: ProgressBar | None) -> None:
    """An operator action: a load to hang (confirm) or a pause to end (resume)."""
    seq = started_plan(daemon.ctrl)
    msg = f"\n>>> {prompt}. Press Enter when done (Ctrl-C twice aborts): "
    if bar is not None:
        bar.clear()
    if not sys.stdin.isatty() and not os.environ.get("PAMD_OPERATOR_STDIN"):
        print(msg + "(no operator terminal: aborting)", file=sys.stderr)
        daemon.submit("stop")
        return
    input(msg)
    verdict = daemon.command("confirm" if seq.phase == "load" else "resume")
    if not verdict["ok"]:
        print(f"pamd: {verdict['error']}", file=sys.stderr)


def _pause_menu(daemon: Daemon, bar: ProgressBar | None) -> None:
    if bar is not None:
        bar.clear()
    while True:
        try:
            answer = input("\npaused at the end of the cycle: [r]esume or [a]bort? ").strip()
        except EOFError:
            answer = "a"
        if answer[:1].lower() == "r":
            daemon.command("resume")
            return
        if answer[:1].lower() == "a":
            daemon.command("stop")
            return


def _bar(total_s: float, show: bool) -> ProgressBar | None:
    if not show:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # progress is a nicety, not a requirement
        return None
    bar: ProgressBar = tqdm(  # tqdm is untyped
        total=round(total_s, 1), unit="s", unit_scale=False, dynamic_ncols=True,
        bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s rig time "
        "[{elapsed}<{remaining}] {postfix}", file=sys.stderr)
    return bar


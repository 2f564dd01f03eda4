"""`pamd tune --method relay`: the pressure loop identified by relay feedback (Astrom-
Hagglund, Klipper's PID_CALIBRATE), run through the daemon and recorded.

Per level (1.5, 3 and 4.5 bar by default): the setpoint ramps to the level and holds
it (the PID and rate feedforward off and a fast slew limit, as for the steps: only the
regulator acts), then the loop's relay element (`pamd.control.relay`) switches the
regulator setpoint between level +/- amplitude on the measured pressure crossing where
it rested (with hysteresis) for a few cycles. From the recording: the ultimate gain
Ku = 4 d / (pi a) and period Tu of the oscillation (`relay_oscillation`), the static
gain K = the rested pressure / the level (a proportional regulator passes 0 bar at 0),
and the FOPDT model that oscillates so (`relay_fopdt`, the hysteresis's phase lag
included); the design model is the mean over the levels, and the gains are the same
SIMC PI and rate feedforward as the step method's.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from pamd.commands.pending import PendingCommand
from pamd.commands.schema import Command
from pamd.commands.tune import RelayArgs
from pamd.config import LoadedConfig, load_config
from pamd.control.relay import DONE
from pamd.control.tuning import (
    Fopdt,
    IdentificationError,
    RelayResult,
    relay_fopdt,
    relay_oscillation,
)
from pamd.daemon import Daemon
from pamd.io.session import RecordingRequest
from pamd.tune.run import PRESSURE, TuneRefused, check_limits, ident_overrides
from pamd.view.recording import open_recording

#: the largest relay amplitude allowed unless --relay-max-bar says otherwise (bar): the
#: loop's working range, as for the steps
MAX_RELAY_BAR = 0.5
#: the switching hysteresis (bar): above the pressure sensor's noise
HYSTERESIS_BAR = 0.02
#: full oscillation periods per level (the first two are the transient)
CYCLES = 8
#: no crossing of the switching level within this after a switch: no oscillation (s)
TIMEOUT_S = 2.0
#: the hold before the relay starts, after the ramp to the level (s)
REST_S = 0.5


@dataclass(frozen=True)
class RelayRun:
    """One level's relay test: where it ran and what it found."""

    level_bar: float
    rest_bar: float  # the pressure where the regulator rested at the level
    start_s: float  # the relay's window in the recording's time
    end_s: float
    oscillation: RelayResult
    model: Fopdt


def check_relay(cfg: LoadedConfig, muscle: str, levels_bar: tuple[float, ...],
                amplitude_bar: float, max_amplitude_bar: float) -> None:
    """Refuse (TuneRefused, with the reason) before anything moves: an amplitude above
    the bound, a level +/- amplitude outside the safe pressure or the pressure limit."""
    if not 0.0 < amplitude_bar <= max_amplitude_bar:
        raise TuneRefused(f"a relay amplitude of {amplitude_bar:g} bar is not allowed: use "
                          f"one above 0 and at most {max_amplitude_bar:g} bar (--relay-max-bar;"
                          " a small relay identifies the loop where it works)")
    if amplitude_bar <= HYSTERESIS_BAR:
        raise TuneRefused(f"a relay amplitude of {amplitude_bar:g} bar is within the "
                          f"switching hysteresis ({HYSTERESIS_BAR:g} bar): use a larger one")
    # the steps' bounds: level - amplitude >= safe pressure, level + amplitude <= limit
    span = 2.0 * amplitude_bar
    check_limits(cfg, muscle, replace(PRESSURE, step_bar=span, max_step_bar=span,
                                      levels_bar=tuple(lv - amplitude_bar
                                                       for lv in levels_bar)))


def run_relay(config_path: str | None, clock: str | None, muscle: str,
              levels_bar: tuple[float, ...], amplitude_bar: float, max_amplitude_bar: float,
              out_dir: str, progress: Callable[[str], None] | None = None) -> list[RelayRun]:
    """Run the relay test at each level on the rig, recorded into `out_dir`."""
    overrides: dict[str, object] = {}
    if clock:
        overrides["loop"] = {"clock": clock}
    base = load_config(config_path, overrides)
    check_relay(base, muscle, levels_bar, amplitude_bar, max_amplitude_bar)
    overrides["control"] = ident_overrides(base, "pressure")
    cfg = load_config(config_path, overrides)
    os.makedirs(out_dir, exist_ok=True)
    daemon = Daemon(cfg, note=f"pamd tune --method relay, +/- {amplitude_bar:g} bar",
                    recording=RecordingRequest(dir=out_dir, run_name=f"tune-relay-{muscle}"))
    try:
        daemon.start()  # RigBusy while another daemon drives this rig
    except BaseException:
        daemon.close()
        raise
    windows: list[tuple[float, float, float, float]] = []
    try:
        for level in levels_bar:
            windows.append(_one_level(daemon, cfg, muscle, level, amplitude_bar,
                                      max_amplitude_bar, progress))
    finally:
        daemon.stop("tuning run ended")
        daemon.wait()
        daemon.close()
    return analyse(out_dir, muscle, windows, amplitude_bar)


def _command(daemon: Daemon, verb: str, args: object, timeout_s: float) -> dict[str, object]:
    pending = PendingCommand()
    daemon.mailbox.put(Command(verb, args, pending.set))
    return pending.result(timeout_s)


def _one_level(daemon: Daemon, cfg: LoadedConfig, muscle: str, level: float,
               amplitude_bar: float, max_amplitude_bar: float,
               progress: Callable[[str], None] | None) -> tuple[float, float, float, float]:
    """(level, rested pressure, start, end) of the relay at `level`."""
    patience = cfg.rig.safety.startup_timeout_s + 5.0
    verdict = daemon.submit("setpoint", {"muscle": muscle, "bar": level}).result(patience)
    if not verdict["ok"]:
        raise TuneRefused(f"{muscle}: the tuning run was refused: {verdict['error']}")
    ramp_s = float(verdict.get("ramp_s") or 0.0)
    m = daemon.ctrl.by_name[muscle]
    t_set = daemon.ctrl.now
    _wait(daemon, lambda: daemon.ctrl.now >= t_set + ramp_s + REST_S, patience + ramp_s)
    if progress is not None:
        progress(f"{muscle}: relay at {level:g} +/- {amplitude_bar:g} bar")
    verdict = _command(daemon, "relay", RelayArgs(
        muscle=muscle, amplitude_bar=amplitude_bar, hysteresis_bar=HYSTERESIS_BAR,
        max_amplitude_bar=max_amplitude_bar, cycles=CYCLES, timeout_s=TIMEOUT_S), patience)
    if not verdict["ok"]:
        raise TuneRefused(f"{muscle}: the relay test was refused: {verdict['error']}")
    started = float(verdict["started_s"])  # type: ignore[arg-type]
    relay = m.pressure_loop.relay
    _wait(daemon, lambda: not relay.active, patience + CYCLES * 4 * TIMEOUT_S)
    if relay.outcome != DONE:
        fault = daemon.ctrl.supervisor.fault_reason or ""
        why = relay.outcome or "the daemon stopped"
        raise TuneRefused(f"{muscle}: the relay test at {level:g} bar stopped: {why}"
                          + (f" ({fault})" if fault else "") + "; the present gains are kept")
    if progress is not None:
        progress(f"{muscle}: {relay.switches // 2} cycles at {level:g} bar")
    return (level, relay.switch_bar, started + relay.relay_start_s, started + relay.elapsed_s)


def _wait(daemon: Daemon, done: Callable[[], bool], timeout_s: float) -> None:
    """Service the daemon until `done()` (loop time; wall-clock `timeout_s` at most)."""
    t0 = time.monotonic()
    while not done():
        if not daemon.alive:
            fault = daemon.ctrl.supervisor.fault_reason or daemon.loop.stopped_reason
            raise TuneRefused(f"the tuning run stopped ({fault}); the present gains are kept")
        if time.monotonic() - t0 > timeout_s:
            raise TuneRefused(f"the tuning run took longer than {timeout_s:g} s; the present "
                              "gains are kept")
        daemon.service()
        time.sleep(0.01)


def analyse(out_dir: str, muscle: str, windows: list[tuple[float, float, float, float]],
            amplitude_bar: float) -> list[RelayRun]:
    """The oscillation of each relay window of the recording and its FOPDT model."""
    rec = open_recording(out_dir, muscle=muscle)[muscle]
    t = np.asarray(rec["t_s"], dtype=float)
    p = np.asarray(rec["pressure_bar"], dtype=float)
    runs: list[RelayRun] = []
    for level, rest, start, end in windows:
        sel = (t >= start) & (t <= end)
        try:
            osc = relay_oscillation(t[sel], p[sel], amplitude_bar)
            model = relay_fopdt(osc, rest / level, HYSTERESIS_BAR)
        except IdentificationError as exc:
            raise TuneRefused(f"{muscle}: the relay test at {level:g} bar was not "
                              f"identified: {exc}; the present gains are kept") from None
        runs.append(RelayRun(level, rest, start, end, osc, model))
    return runs


def mean_relay_model(runs: list[RelayRun]) -> Fopdt:
    return Fopdt(float(np.mean([r.model.gain for r in runs])),
                 float(np.mean([r.model.tau_s for r in runs])),
                 float(np.mean([r.model.dead_time_s for r in runs])))


def print_relay(title: str, runs: list[RelayRun], model: Fopdt) -> None:
    print(title)
    print(f"  {'level':>7s} {'rest bar':>8s} {'Tu ms':>7s} {'a bar':>7s} {'Ku':>7s} "
          f"{'K':>6s} {'dead ms':>8s} {'lag ms':>7s}")
    for r in runs:
        o = r.oscillation
        print(f"  {r.level_bar:7.2f} {r.rest_bar:8.3f} {1e3 * o.ultimate_period_s:7.1f} "
              f"{o.amplitude:7.4f} {o.ultimate_gain:7.2f} {r.model.gain:6.3f} "
              f"{1e3 * r.model.dead_time_s:8.1f} {1e3 * r.model.tau_s:7.1f}")
    print(f"  model (mean): gain {model.gain:.3f} bar/bar, dead time "
          f"{1e3 * model.dead_time_s:.1f} ms, lag {1e3 * model.tau_s:.1f} ms")

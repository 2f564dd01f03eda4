"""`pamd tune --method relay`: the pressure loop identified by relay feedback (Astrom-
Hagglund, Klipper's PID_CALIBRATE), run through the daemon and recorded.

Per level (1.5, 3 and 4.5 bar by default): the setpoint ramps to the level and holds
it (the PID and rate feedforward off and a fast slew limit, as for the steps: only the
regulator acts), then the loop's relay element (`pamd.loop.control.relay`) switches the
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

from pamd.client.recording import open_recording
from pamd.client.tune.ident_run import PRESSURE, TuneRefused, check_limits, start, tuning_config
from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.loop.commands.pending import PendingCommand
from pamd.loop.commands.tune_verbs import RelayArgs
from pamd.loop.control.relay import DONE
from pamd.loop.control.tuning import (
    Fopdt,
    IdentificationError,
    RelayResult,
    relay_fopdt,
    relay_oscillation,
)
from pamd.wire.verbs.args import Command

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
    """Run the relay test at each level on the rig, each level a daemon run recorded
    into `out_dir/<level>`; their oscillations and models."""
    cfg = tuning_config(config_path, clock, "pressure", lambda base: check_relay(
        base, muscle, levels_bar, amplitude_bar, max_amplitude_bar))
    runs: list[RelayRun] = []
    for level in levels_bar:
        level_dir = os.path.join(out_dir, f"{level:g}-bar".replace(".", "_"))
        rest = _one_level(cfg, muscle, level, amplitude_bar, max_amplitude_bar, level_dir,
                          progress)
        runs.append(analyse(level_dir, muscle, level, rest, amplitude_bar))
    return runs


def _one_level(cfg: LoadedConfig, muscle: str, level: float, amplitude_bar: float,
               max_amplitude_bar: float, out_dir: str,
               progress: Callable[[str], None] | None) -> float:
    """The relay at `level`, one daemon run (the command queued before it starts, so
    everything happens in loop time); the pressure where the regulator rested."""
    os.makedirs(out_dir, exist_ok=True)
    daemon = Daemon(cfg, note=f"pamd tune --method relay at {level:g} +/- "
                    f"{amplitude_bar:g} bar",
                    recording=RecordingRequest(dir=out_dir, run_name=f"tune-relay-{muscle}"))
    pending = PendingCommand()
    daemon.mailbox.put(Command("relay", RelayArgs(
        muscle=muscle, center_bar=level, amplitude_bar=amplitude_bar,
        hysteresis_bar=HYSTERESIS_BAR, max_amplitude_bar=max_amplitude_bar, cycles=CYCLES,
        timeout_s=TIMEOUT_S, hold_s=REST_S), pending.set))
    start(daemon)  # RigBusy while another daemon drives this rig
    relay = daemon.ctrl.by_name[muscle].pressure_loop.relay
    patience = cfg.rig.safety.startup_timeout_s + 5.0
    try:
        verdict = pending.result(patience)
        if not verdict["ok"]:
            raise TuneRefused(f"{muscle}: the relay test was refused: {verdict['error']}")
        if progress is not None:
            progress(f"{muscle}: relay at {level:g} +/- {amplitude_bar:g} bar")
        _wait(daemon, lambda: bool(relay.outcome), patience + CYCLES * 4 * TIMEOUT_S)
    finally:
        daemon.stop("tuning run ended")
        daemon.wait()
        daemon.close()
    if relay.outcome != DONE:
        fault = daemon.ctrl.supervisor.fault_reason or ""
        raise TuneRefused(f"{muscle}: the relay test at {level:g} bar stopped: "
                          f"{relay.outcome}" + (f" ({fault})" if fault else "")
                          + f"; the present gains are kept; its recording is in {out_dir}")
    if progress is not None:
        progress(f"{muscle}: {relay.switches // 2} cycles at {level:g} bar")
    return relay.switch_bar


def _wait(daemon: Daemon, done: Callable[[], bool], timeout_s: float) -> None:
    """Service the daemon until `done()` (wall-clock `timeout_s` at most)."""
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


def analyse(out_dir: str, muscle: str, level: float, rest: float,
            amplitude_bar: float) -> RelayRun:
    """The oscillation in the recording (where the regulator setpoint left the level by
    the relay's amplitude) and its FOPDT model."""
    rec = open_recording(out_dir, muscle=muscle)[muscle]
    t = np.asarray(rec["t_s"], dtype=float)
    u = np.asarray(rec["valve_cmd_bar"], dtype=float)
    p = np.asarray(rec["pressure_bar"], dtype=float)
    setpoint = np.asarray(rec["setpoint_bar"], dtype=float)
    at_level = np.nonzero(np.abs(setpoint - level) < 1e-9)[0]  # the ramp there done
    first = int(at_level[0]) if at_level.size else len(u)
    left = first + np.nonzero(np.abs(setpoint[first:] - level) > 1e-9)[0]  # the stop's ramp
    end = int(left[0]) if left.size else len(u)
    on = first + np.nonzero(np.abs(u[first:end] - level) > 0.5 * amplitude_bar)[0]
    try:
        if on.size == 0:
            raise IdentificationError("the relay never switched")
        sel = slice(int(on[0]), int(on[-1]) + 1)
        osc = relay_oscillation(t[sel], p[sel], amplitude_bar)
        model = relay_fopdt(osc, rest / level, HYSTERESIS_BAR)
    except IdentificationError as exc:
        raise TuneRefused(f"{muscle}: the relay test at {level:g} bar was not "
                          f"identified: {exc}; the present gains are kept") from None
    return RelayRun(level, rest, float(t[sel][0]), float(t[sel][-1]), osc, model)


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

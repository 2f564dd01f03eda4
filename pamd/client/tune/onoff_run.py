"""The step test of `pamd tune --loop onoff`, run through the daemon and recorded like
any run (`pamd.client.tune.onoff_steps` says what it measures and derives).

The daemon runs the rig's own config; its setpoint goes to the level (a `setpoint`
command, queued before it starts) and holds there `SETTLE_S`; then each pulse is one
`pulse` command (`pamd.loop.commands.tune_verbs`: checked against the muscle's valves and
limits, then timed in the tick by `pamd.loop.control.valve_pulse`), sent once the one
before is done. On the virtual clock the loop's time stands still between them
(`Loop.stand_still_while`), so the run is the same however fast this thread is. Each
pulse's verdict says at which recorded time the loop took it; the analysis finds the
pulse there in the recording (its valve's flag, INFLATE_OPEN or EXHAUST_OPEN).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from pamd.client.recording import open_recording
from pamd.client.tune.ident_run import TuneRefused, start
from pamd.client.tune.onoff_steps import (
    AFTER_S,
    IDENT_DEAD_BAND_BAR,
    LEVEL_BAR,
    PULSES,
    SETTLE_S,
    WINDOW_S,
    Pulse,
    PulseResponse,
    StepTest,
    check,
    response,
    smallest_change_mm,
)
from pamd.config import LoadedConfig, load_config
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.loop.commands.pending import PendingCommand
from pamd.loop.commands.tune_verbs import PulseArgs
from pamd.loop.control.actuation import OnOffActuation, min_pulse_s
from pamd.loop.control.relay import DONE
from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.tick import State
from pamd.wire.verbs.args import Command, SetpointArgs

Progress = Callable[[str], None]
#: told the step test as measured, before it is checked (`pamd tune --plot` draws a
#: refused one too)
Measured = Callable[[StepTest], None]
#: the setpoint reaches the level and the PWM holds it within this (s of loop time)
LEVEL_TIMEOUT_S = 30.0


def ident_config(cfg: LoadedConfig, muscle: str) -> LoadedConfig:
    """The identification run's config: the rig's, with the muscle's PWM dead band
    opened to `IDENT_DEAD_BAND_BAR`, so that once the setpoint holds the level the PWM
    leaves the valves to the pulses (the pressure wanders by a pulse's step, never
    further than the band, without a correction between pulses)."""
    muscles = tuple(replace(m, onoff=replace(m.onoff, dead_band_bar=IDENT_DEAD_BAND_BAR))
                    if m.name == muscle else m for m in cfg.rig.muscles)
    return replace(cfg, rig=replace(cfg.rig, muscles=muscles))


def check_onoff(cfg: LoadedConfig, muscle: str, level_bar: float) -> None:
    """Refuse (TuneRefused, with the reason) before anything opens: a muscle that is
    not on this rig or not on on/off valves, a level outside its safe range."""
    names = [m.name for m in cfg.rig.muscles]
    if muscle not in names:
        raise TuneRefused(f"no muscle {muscle!r} on this rig (it has {', '.join(names)})")
    if cfg.muscle(muscle).actuation != "onoff":
        raise TuneRefused(f"{muscle} has a pressure regulator, not on/off valves: --loop "
                          "onoff tunes on/off valves; tune its loops with --loop pressure "
                          "and --loop position")
    env = MuscleEnvelope.from_config(cfg, muscle)
    load = cfg.muscle(muscle).load_kg
    low, high = env.safe_pressure_bar(load), env.max_pressure_bar
    if not low < level_bar < high:
        raise TuneRefused(f"{muscle}: the step test's level {level_bar:g} bar is outside "
                          f"{low:.2f}-{high:g} bar (the safe pressure with {load:g} kg to the "
                          "pressure limit): choose a level in between with --levels")


class _Session:
    """The step test's commands, one at a time. `idle` (the loop's thread, at the start
    of a tick, on the virtual clock; this thread asks it too): nothing queued, no pulse
    running, and the PWM has held the level `SETTLE_S` (once, before the first
    pulse)."""

    def __init__(self, daemon: Daemon, muscle: str, level_bar: float) -> None:
        self._daemon = daemon
        self._m = daemon.ctrl.by_name[muscle]
        act = self._m.actuation
        assert isinstance(act, OnOffActuation)  # check_onoff
        self.act = act
        self._level = level_bar
        self._rest_since = -1.0  # loop time the PWM began to hold the level (-1: it does not)
        self._settled = False  # held SETTLE_S: the pulses may begin
        self._pending: PendingCommand | None = None
        self._virtual = daemon.loop.virtual
        self._stood = False  # idle's last answer

    def idle(self) -> bool:
        ready = self._idle()
        self._stood = ready
        return ready

    def ready(self) -> bool:
        """This thread: may the next command go? On the virtual clock: the loop stands
        still for it (`idle` said so, in the loop's thread); on the real one, `idle`."""
        return self._stood if self._virtual else self.idle()

    def _idle(self) -> bool:
        ctrl = self._daemon.ctrl
        if ctrl.supervisor.state == State.STARTING:
            return False
        if self._pending is not None and not self._pending.done:
            return False  # the command queued is taken at this tick
        if self._settled:
            return not self.act.pulse.active
        if self._m.setpoint_bar != self._level or not self.act.holding:
            self._rest_since = -1.0
            return False
        if self._rest_since < 0.0:
            self._rest_since = ctrl.now
        self._settled = ctrl.now - self._rest_since >= SETTLE_S
        return self._settled

    def expect(self, pending: PendingCommand) -> None:
        """A command queued before the start: the loop goes on until it takes it."""
        self._pending = pending

    def send(self, cmd: Command, pending: PendingCommand) -> JsonObject:
        """Queue `cmd`, let the loop go on and wait for its verdict."""
        self._pending = pending
        self._stood = False
        self._daemon.mailbox.put(cmd)
        self._daemon.loop.wake()
        return pending.result(self._daemon.cfg.rig.safety.startup_timeout_s + 5.0)

    def wait(self, done: Callable[[], bool], timeout_s: float) -> None:
        """Service the daemon until `done()`; TuneRefused when the run stopped."""
        daemon = self._daemon
        t0 = time.monotonic()
        while not done():
            if not daemon.alive or daemon.ctrl.supervisor.latched:
                sup = daemon.ctrl.supervisor
                why = sup.fault_reason or daemon.loop.stopped_reason or sup.state.name
                raise TuneRefused(f"the step test stopped ({why})")
            if time.monotonic() - t0 > timeout_s:
                raise TuneRefused(f"the step test took longer than {timeout_s:g} s")
            daemon.service()
            time.sleep(0.005)


def run_onoff(config_path: str | None, clock: str | None, muscle: str, out_dir: str,
              level_bar: float = LEVEL_BAR, progress: Progress | None = None,
              measured: Measured | None = None) -> StepTest:
    """Run the step test on the rig, recorded into `out_dir`; what the recording shows
    (`measured` is told it before it is checked). TuneRefused (the present settings
    kept) when it stops or measures nothing."""
    cfg = load_config(config_path, {"loop": {"clock": clock}} if clock else None)
    check_onoff(cfg, muscle, level_bar)
    cfg = ident_config(cfg, muscle)
    shortest = min_pulse_s(cfg.muscle(muscle).onoff)
    os.makedirs(out_dir, exist_ok=True)
    daemon = Daemon(cfg, note=f"pamd tune --loop onoff: the step test of {muscle} at "
                    f"{level_bar:g} bar (its PWM dead band opened to {IDENT_DEAD_BAND_BAR:g} bar)",
                    recording=RecordingRequest(
                        dir=out_dir, run_name=f"tune-onoff-{muscle}"))
    session = _Session(daemon, muscle, level_bar)
    daemon.loop.stand_still_while(session.idle)
    first = PendingCommand()
    session.expect(first)
    daemon.mailbox.put(Command("setpoint", SetpointArgs(muscle=muscle, bar=level_bar),
                               first.set))
    start(daemon)  # RigBusy while another daemon drives this rig
    sent: list[tuple[Pulse, float]] = []
    patience = cfg.rig.safety.startup_timeout_s + 5.0
    try:
        verdict = first.result(patience)
        if not verdict["ok"]:
            raise TuneRefused(f"the setpoint {level_bar:g} bar was refused: {verdict['error']}")
        if progress is not None:
            progress(f"{muscle}: to {level_bar:g} bar, held {SETTLE_S:g} s")
        session.wait(lambda: _settled(session, daemon, level_bar), patience + 60.0)
        for pulse in PULSES:
            session.wait(session.ready, patience)
            sent.append((pulse, _pulse(session, muscle, pulse, shortest, progress)))
            session.wait(lambda: not session.act.pulse.active, patience)
            outcome = session.act.pulse.outcome
            if outcome != DONE:
                raise TuneRefused(f"the {pulse.valve} pulse stopped: {outcome}")
    except TuneRefused as exc:
        raise TuneRefused(f"{muscle}: {exc}; the present settings are kept; the recording "
                          f"is in {out_dir}") from None
    finally:
        daemon.stop("tuning run ended")
        daemon.wait()
        daemon.close()
    return analyse(out_dir, muscle, sent, shortest, measured)


def _settled(session: _Session, daemon: Daemon, level_bar: float) -> bool:
    """The level held `SETTLE_S`: the pulses may begin (TuneRefused past
    LEVEL_TIMEOUT_S of the loop's time)."""
    if session.ready():
        return True
    if daemon.ctrl.now - daemon.ctrl.t_start > LEVEL_TIMEOUT_S:
        raise TuneRefused(f"the PWM did not hold {level_bar:g} bar within "
                          f"{LEVEL_TIMEOUT_S:g} s (no supply, a valve that does not open?)")
    return False


def _pulse(session: _Session, muscle: str, pulse: Pulse, shortest_s: float,
           progress: Progress | None) -> float:
    """Send one pulse; the recorded time at which the loop took it."""
    length = pulse.length_s(shortest_s)
    pending = PendingCommand()
    verdict = session.send(Command("pulse", PulseArgs(
        muscle=muscle, valve=pulse.valve, pulse_s=length, rest_s=WINDOW_S,
        after_s=AFTER_S), pending.set), pending)
    if not verdict["ok"]:
        raise TuneRefused(f"the {1e3 * length:g} ms {pulse.valve} pulse was refused: "
                          f"{verdict['error']}")
    if progress is not None:
        progress(f"{muscle}: {pulse.valve} valve open {1e3 * length:g} ms")
    t_s = verdict["t_s"]
    assert isinstance(t_s, float)
    return t_s


def analyse(out_dir: str, muscle: str, sent: list[tuple[Pulse, float]],
            shortest_s: float, measured: Measured | None = None) -> StepTest:
    """The step test in the recording: each pulse where its verdict says (see
    `pamd.client.tune.onoff_steps.response`); the encoder's count over every tick measured. The
    recording is read once: each pulse's response keeps its stretch of it (its trace)."""
    rec = open_recording(out_dir, muscle=muscle)[muscle]
    t = np.asarray(rec["t_s"], dtype=float)
    p = np.asarray(rec["pressure_bar"], dtype=float)
    length = np.asarray(rec["length_mm"], dtype=float)
    flags = np.nan_to_num(np.asarray(rec["flags"], dtype=float), nan=0.0)
    try:
        found = [response(t, p, length, flags, pulse, t_s, shortest_s) for pulse, t_s in sent]
        spans = [span for _, span in found]
        r: list[PulseResponse] = [resp for resp, _ in found]
        test = StepTest.of(r, smallest_change_mm(length[spans[0].start:spans[-1].stop]))
        if measured is not None:
            measured(test)
        check(test)
    except TuneRefused as exc:
        raise TuneRefused(f"{muscle}: {exc}; the present settings are kept; the recording "
                          f"is in {out_dir}") from None
    return test

"""What `pamd run` asks of the rig from its start (a `--mode`, a `--profile`), and
the declared loads' verdict.

The requests are sent once the start-up is over (the sensors read, every declared
load checked against the force at rest: `pamd.loop.control.rig_startup`) and the rig is at
rest: a muscle that started outside its limits (stretched past its pretension limit
under a heavy load, say) first ramps to its safe pressure, and the requests wait for
that ramp (bounded, said on stderr) instead of cutting it short or being refused for
it. On the virtual clock the loop's time stands still while they are sent
(`Loop.stand_still_while`), so a virtual run is the same every time.

A declared load the force at rest disagrees with, in a run that refuses it (a run
with an end: `pamd.loop.control.controller.RigController.refuse_wrong_load`), is a `ConfigError`
(exit 2) naming both loads, the key (file and line, or `--load-kg`) and what to do.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Collection

from pamd.daemon.daemon import Daemon
from pamd.loop.commands.pending import PendingCommand
from pamd.loop.safety.load_check import LoadDisagreement
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused, ConfigError, ConfigIssue
from pamd.wire.schema.engine import line_of
from pamd.wire.schema.yamlload import load_yaml_text
from pamd.wire.tick import State

log = logging.getLogger("pamd")

#: The ramp to the safe pressure may take this much longer than its slew limit says
#: (its pace shared with other muscles, a busy machine), plus RAMP_SLACK_S, before the
#: requests waiting for it are refused.
RAMP_PATIENCE = 1.5
RAMP_SLACK_S = 2.0


class StartRequests:
    """The commands a run asks for from its start, sent after the start-up and its
    ramp (see the module's doc). Build before `Daemon.start`, then `send()`."""

    def __init__(self, daemon: Daemon, requests: list[tuple[str, JsonObject]],
                 loads_given: Collection[str] = ()) -> None:
        """`loads_given`: the muscles whose load `--load-kg` gave (a refusal names it)."""
        self.d = daemon
        self.requests = requests
        self.loads_given = loads_given
        self.sent = not requests
        self.seen = False  # the main thread has seen the start-up's end
        self.deadline_s = math.inf  # loop time by which the ramp must have ended
        if requests:
            daemon.loop.stand_still_while(self._loop_waits)

    def _loop_waits(self) -> bool:
        """Asked by the loop's thread (virtual clock) at the start of a tick: stand
        still once the start-up is over until the main thread has looked, and again
        once the rig rests (or the ramp's time is up) until the requests are sent."""
        if self.sent:
            return False
        ctrl = self.d.ctrl
        if ctrl.supervisor.state == State.STARTING:
            return False
        return (not self.seen or ctrl.supervisor.latched or ctrl.at_rest()
                or ctrl.now >= self.deadline_s)

    def send(self, patience_s: float) -> None:
        """Wait for the start-up (at most `patience_s`), raise the load refusal if there
        is one, wait for the ramp to rest, then send every request and wait for its
        verdict; a refusal stops the run (nothing moved) and raises CommandRefused."""
        d = self.d
        self._until(lambda: d.ctrl.supervisor.state != State.STARTING, patience_s)
        self.refuse_wrong_load()
        if self.sent:
            return
        ctrl = d.ctrl
        if not (ctrl.supervisor.latched or ctrl.at_rest()):
            self._announce_ramp()
        self.seen = True
        d.loop.wake()
        self._until(lambda: ctrl.supervisor.latched or ctrl.at_rest()
                    or ctrl.now >= self.deadline_s, math.inf)
        if not (ctrl.supervisor.latched or ctrl.at_rest()) and d.alive:
            self._stop(f"the start-up's ramp to the safe pressure did not end within "
                       f"{self.deadline_s - ctrl.t_start:.1f} s of the start ({ctrl.rest_text()})")
        pending: list[tuple[str, PendingCommand]] = []
        for verb, payload in self.requests:
            pending.append((verb, d.submit(verb, payload)))
        self.sent = True
        d.loop.wake()
        for verb, p in pending:
            self._until(lambda: p.done, patience_s)  # noqa: B023 - waited for at once
            verdict = p.result(0.0)
            if not verdict["ok"]:
                self._stop(verdict["error"], f"{verb} refused")

    def _announce_ramp(self) -> None:
        """Say on stderr what the requests wait for, and bound it."""
        ctrl = self.d.ctrl
        ramps = [m for m in ctrl.muscles if m.in_safe_ramp]
        ramp_s = max((m.safe_entry_s(False) for m in ramps), default=0.0)
        bound_s = RAMP_PATIENCE * ramp_s + RAMP_SLACK_S
        self.deadline_s = ctrl.now + bound_s
        what = " and ".join(f"--{verb}" for verb, _ in self.requests)
        log.info("%s started outside the limits and ramps to %s; %s wait%s for the ramp "
                 "(about %.1f s, at most %.1f s)", ", ".join(m.name for m in ramps),
                 ", ".join(f"its safe pressure {m.safe_pressure_bar:.2f} bar" for m in ramps),
                 what, "" if len(self.requests) > 1 else "s", ramp_s, bound_s)

    def _until(self, done: Callable[[], bool], patience_s: float) -> None:
        waited = 0.0
        while not done() and waited < patience_s and self.d.alive:
            self.d.wait(timeout_s=0.05)  # keeps service() (notify, state) running
            waited += 0.05

    def _stop(self, error: str, why: str = "start refused") -> None:
        self.sent = True
        self.d.loop.wake()
        self.d.stop(why)
        self.d.wait()
        raise CommandRefused(error)

    def refuse_wrong_load(self) -> None:
        """A run that refuses a wrong declared load (`refuse_wrong_load`) and found one
        at start-up: ConfigError (exit 2), nothing written."""
        ctrl = self.d.ctrl
        if not (ctrl.refuse_wrong_load and ctrl.load_disagreements):
            return
        self.sent = True
        self.d.loop.wake()
        self.d.stop("the declared load disagrees with the force at rest")
        self.d.wait()
        raise load_refusal(self.d, ctrl.load_disagreements, self.loads_given)


def load_refusal(d: Daemon, wrong: tuple[LoadDisagreement, ...],
                 loads_given: Collection[str] = ()) -> ConfigError:
    """The refusal of declared loads the force at rest disagrees with: per muscle the
    key it came from (the config file and line, or `--load-kg`), both loads and what
    to do."""
    cfg = d.cfg
    try:
        root = load_yaml_text(cfg.text, cfg.path)
    except Exception:  # noqa: BLE001 - only for the line number
        root = None
    muscles = root.get("muscles") if isinstance(root, dict) else None
    issues = []
    for w in wrong:
        i = next(k for k, m in enumerate(cfg.rig.muscles) if m.name == w.muscle)
        item = muscles[i] if isinstance(muscles, list) and i < len(muscles) else None
        from_cli = w.muscle in loads_given
        file, line = (("--load-kg", None) if from_cli
                      else (cfg.path, line_of(item, "load_kg")))
        issues.append(ConfigIssue(
            file, line, w.muscle if from_cli else f"muscles[{i}].load_kg",
            f"the load that hangs: {w.text()}; nothing was written. Declare the load that "
            f"hangs (load_kg, or pamd run --load-kg {w.muscle}={w.measured_kg:.1f} for one "
            "run), hang the declared one, or, where no dead weight hangs (a spring, an "
            "antagonist, a load on a stop), set dead_weight: false",
            f"{w.declared_kg:g} kg"))
    return ConfigError(issues)

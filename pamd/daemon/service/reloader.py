"""SIGHUP (one job of the service keeper, `pamd.daemon.service.keeper`): the config is read
again, validated and applied through the loop's mailbox (`pamd.daemon.service.reload` plans
what applies when); limits and loads wait for the rig to rest; changes that reopen the
devices wait for rest too and then restart the daemon in place
(`pamd.daemon.service.restart`), where `pamd run` allows it (`allow_restart_in_place`). A
reload that fails is refused and the daemon runs on the config loaded before: a
reload never takes the rig down.

**Off the loop.** The file is read, parsed, validated and its model files checked in a
child process (`pamd.loop.commands.model_file.read_config_isolated`), waited for by a
worker thread; the main thread only looks whether it is done, every 50 ms, so the
status, the persistence and systemd's notifications go on meanwhile (the watchdog's
pings come from a thread of their own and prove only that the loop ticks). On the
virtual clock (a simulation, no deadline to keep) it is read in the calling thread.

**One at a time.** A SIGHUP during start-up waits until the rig has started; one
while a reload is read or waits for its verdict is queued, and the file is read again
once that one is over. Each says so in the log.

**What status shows** (`reload`, the controller's `reload_note`): `outcome` pending
(being read, waiting for the rig to rest, or for rest to restart in place), applied,
refused (with the reason: invalid YAML, a limit below what is held, ...) or
restarting, with the `keys` and the `reason`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import Future

from pamd.config.loader import LoadedConfig
from pamd.daemon.service.notify import Notifier
from pamd.daemon.service.ports import KeptLoop, KeptRig
from pamd.daemon.service.reload import ReloadPlan, describe, plan_reload
from pamd.loop.commands import Command
from pamd.loop.commands.model_file import read_config, read_config_isolated
from pamd.loop.commands.offload import Preparer
from pamd.loop.commands.pending import PendingCommand
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import PamdError
from pamd.wire.tick import State

log = logging.getLogger("pamd")


class Reloader:
    """One daemon's config reloads: the configs in force (as started, the gains', the
    limits'), the file being read (`reading`), the reload waiting for its verdict
    (`pending`), one deferred until the rig rests (`deferred`) and a restart in place
    waiting for rest (`handover`)."""

    def __init__(self, rig: KeptRig, loop: KeptLoop, submit: Callable[[Command], None],
                 config: Callable[[], LoadedConfig],
                 apply_config: Callable[[LoadedConfig], None], notifier: Notifier,
                 finished: Callable[[], None],
                 config_overrides: JsonObject | None = None,
                 handing_over: Callable[[], None] = lambda: None) -> None:
        """`submit`: a command into the loop's mailbox; `config`: the config in force;
        `apply_config`: once a reload is in force; `finished`: a reload is over
        (applied, deferred or refused: READY=1 again); `handing_over`: the loop is
        asked to hand over for a restart in place."""
        self.rig = rig
        self.supervisor = rig.supervisor
        self.loop = loop
        self.submit = submit
        self.config = config
        self.apply_config = apply_config
        self.notifier = notifier
        self._finish = finished
        self._handing_over = handing_over
        self.config_overrides = config_overrides
        self.requested = False
        self.started_cfg: LoadedConfig = config()
        self.gains_cfg: LoadedConfig = self.started_cfg
        self.limits_cfg: LoadedConfig = self.started_cfg
        self.reading: Future[LoadedConfig] | None = None  # the file read off the loop
        self.pending: tuple[ReloadPlan, PendingCommand] | None = None
        self.deferred: ReloadPlan | None = None
        # changes that reopen the devices: `pamd run` can restart in place (a
        # library daemon, a virtual run cannot, and such a reload is refused)
        self.restart_in_place = False
        self.handover: str | None = None  # the changes a restart waiting for rest applies
        self.handing_over = False  # the loop was asked to end at a tick at rest
        self._preparer = Preparer()
        self._queued_said = False
        # how a reload's file is read off the loop (a test hook may slow it down)
        self.read: Callable[[str, JsonObject | None], LoadedConfig] = read_config_isolated

    def service(self) -> None:
        """Every 50 ms: a read or a verdict come back, a SIGHUP asked, the rig come to
        rest for what waits for it."""
        if self.reading is not None:
            if not self.reading.done():
                self._queue_said("a reload is being read")
                return
            self._read_done(self.reading)
        if self.pending is not None:
            plan, pending = self.pending
            if not pending.done:
                self._queue_said("a reload waits for the loop's verdict")
                return  # one reload at a time; a new SIGHUP waits for this verdict
            self.pending = None
            self._verdict(plan, pending.verdict)
        if self.requested and self.supervisor.state == State.STARTING:
            self._queue_said("the rig is starting")
        elif self.requested:
            self.requested = False
            self._queued_said = False
            try:
                self._begin()
            except Exception:  # a reload must never take the running rig down
                log.exception("reload failed; still running on the config loaded before")
                self._finish()
        elif (self.handover is not None and not self.handing_over and self.pending is None
              and self.rig.at_rest()):  # not during a stop's ramp
            self.handing_over = True
            self._handing_over()
            self.notifier.reloading()
            self._note("restarting", self.handover, "the rig is at rest: the loop ends "
                       "holding the outputs, then pamd restarts in place")
            log.warning("the rig is at rest: the loop ends holding the outputs, then pamd "
                        "restarts in place (%s)", self.handover)
            self.loop.request_handover(f"config reload: {self.handover}")
        elif (self.deferred is not None and self.pending is None
              and self.rig.at_rest()):  # not during a stop's ramp (issue 23)
            plan = self._plan(self.deferred.cfg)
            log.info("the rig is at rest: applying the deferred reload (%s)",
                     ", ".join(plan.idle) or "nothing left")
            self._submit(plan)

    def close(self) -> None:
        """The daemon closes: a read still under way is left to end by itself."""
        self._preparer.close()

    def _queue_said(self, why: str) -> None:
        if self.requested and not self._queued_said:
            self._queued_said = True
            log.warning("SIGHUP: %s; this reload is queued and reads %s once it is over",
                        why, self.config().path)

    def _plan(self, new: LoadedConfig) -> ReloadPlan:
        return plan_reload(self.started_cfg, self.gains_cfg, self.limits_cfg, new)

    def _note(self, outcome: str, keys: list[str] | str, reason: str) -> None:
        """What status shows of the reload (`reload`)."""
        self.rig.reload_note = {"outcome": outcome,
                                "keys": [keys] if isinstance(keys, str) else list(keys),
                                "t_s": self.rig.now, "reason": reason}

    def _begin(self) -> None:
        path = self.config().path
        self.notifier.reloading()
        log.info("SIGHUP: reloading %s", path)
        self._note("pending", [], f"{path} is being read and checked")
        if self.loop.virtual:  # a simulation: no deadline, read here
            done: Future[LoadedConfig] = Future()
            try:
                done.set_result(read_config(path, self.config_overrides))
            except Exception as exc:  # noqa: BLE001 - refused below, never raised
                done.set_exception(exc)
            self._read_done(done)
            return
        # off the loop: in a child process, waited for by a worker thread
        self.reading = self._preparer.submit(self.read, path, self.config_overrides)

    def _read_done(self, done: Future[LoadedConfig]) -> None:
        self.reading = None
        path = self.config().path
        try:
            new = done.result()
        except PamdError as exc:
            self._refuse(f"{exc}")
            return
        except Exception as exc:  # noqa: BLE001 - a reload must never take the daemon down
            self._refuse(f"{type(exc).__name__}: {exc}")
            return
        plan = self._plan(new)
        if self.handing_over:
            log.warning("reload: pamd is restarting in place already; the restarted daemon "
                        "reads %s again", path)
            return
        if self.handover is not None:
            log.info("reload: the restart in place waiting for rest is superseded by this "
                     "reload")
            self.handover = None
        if plan.restart:
            self._restart_when_at_rest(plan)
            return
        if self.deferred is not None:
            log.info("reload: the deferred reload is superseded by this one")
            self.deferred = None
        if not (plan.now or plan.idle):
            log.info("reload: %s has no changes to apply", path)
            self._note("applied", [], "no changes")
            self._finish()
            return
        self._submit(plan)

    def _refuse(self, reason: str) -> None:
        log.error("reload refused, still running on the config loaded before: %s", reason)
        self._note("refused", [], reason)
        self._finish()

    def _restart_when_at_rest(self, plan: ReloadPlan) -> None:
        """Changes that reopen the devices: a restart in place once the rig rests
        (`service`: IDLE, no profile, a stop's ramp to the safe state completed), or
        refused where this daemon cannot restart in place."""
        what = describe(plan.restart, self.started_cfg, plan.cfg)
        if not self.restart_in_place or self.loop.virtual:
            why = ("a virtual-clock run" if self.loop.virtual
                   else "this daemon is not `pamd run`")
            self._refuse(f"{what} changed, which reopens the devices, and {why} cannot "
                         "restart in place: needs a restart (systemctl restart pamd)")
            return
        self.deferred = None  # the restart applies everything
        self.handover = what
        at_rest = self.rig.at_rest()
        rest = "now (the rig is at rest)" if at_rest else (
            f"once the rig is at rest (it is {self.rig.rest_text()}; `pamd cmd stop` ends "
            "what runs)")
        self._note("pending", plan.restart, f"reopens the devices: pamd restarts in place {rest}")
        log.warning("reload: %s changed, which reopens the devices: pamd restarts in place "
                    "%s", what, rest)
        if not at_rest:
            self._finish()

    def _submit(self, plan: ReloadPlan) -> None:
        pending = PendingCommand()
        self.submit(Command("reload", plan.args, pending.set, sender="SIGHUP"))
        self.pending = (plan, pending)

    def _verdict(self, plan: ReloadPlan, verdict: JsonObject) -> None:
        if not verdict.get("ok"):
            log.error("reload refused: %s", verdict.get("error"))
            self.deferred = None
            self._finish()
            return
        old_gains, self.gains_cfg = self.gains_cfg, plan.cfg
        self.loop.set_stall_limits(plan.cfg)
        if plan.now:
            log.warning("reload: applied at once: %s", describe(plan.now, old_gains, plan.cfg))
        if verdict.get("deferred"):
            self.deferred = plan
            log.warning("reload: deferred until the rig is at rest (it is %s): %s",
                        verdict.get("state"), ", ".join(verdict["deferred"]))
        else:
            self.deferred = None
            if plan.idle:
                log.warning("reload: applied while IDLE: %s",
                            describe(plan.idle, self.limits_cfg, plan.cfg))
            self.limits_cfg = plan.cfg
            self.apply_config(plan.cfg)  # everything in it is now in force
        self._finish()

"""SIGHUP (one job of the service keeper, `pamd.service.keeper`): the config is read
again, validated and applied through the loop's mailbox (`pamd.service.reload` plans
what applies when); limits and loads wait for the rig to rest; changes that reopen the
devices wait for IDLE and then restart the daemon in place (`pamd.service.restart`),
where `pamd run` allows it (`allow_restart_in_place`). A reload that fails is refused
and the daemon runs on the config loaded before: a reload never takes the rig down."""

from __future__ import annotations

import logging
from collections.abc import Callable

from pamd.commands import Command
from pamd.commands.model_file import check_models_isolated
from pamd.commands.pending import PendingCommand
from pamd.config.loader import LoadedConfig, load_config
from pamd.declare.jsonsafe import JsonObject
from pamd.errors import PamdError
from pamd.service.notify import Notifier
from pamd.service.ports import KeptLoop, KeptRig
from pamd.service.reload import ReloadPlan, describe, plan_reload
from pamd.tick import State

log = logging.getLogger("pamd")


class Reloader:
    """One daemon's config reloads: the configs in force (as started, the gains', the
    limits'), the reload waiting for its verdict (`pending`), one deferred until the
    rig rests (`deferred`) and a restart in place waiting for IDLE (`handover`)."""

    def __init__(self, rig: KeptRig, loop: KeptLoop, submit: Callable[[Command], None],
                 config: Callable[[], LoadedConfig],
                 apply_config: Callable[[LoadedConfig], None], notifier: Notifier,
                 finished: Callable[[], None],
                 config_overrides: JsonObject | None = None) -> None:
        """`submit`: a command into the loop's mailbox; `config`: the config in force;
        `apply_config`: once a reload is in force; `finished`: a reload is over
        (applied, deferred or refused: READY=1 again)."""
        self.rig = rig
        self.supervisor = rig.supervisor
        self.loop = loop
        self.submit = submit
        self.config = config
        self.apply_config = apply_config
        self.notifier = notifier
        self._finish = finished
        self.config_overrides = config_overrides
        self.requested = False
        self.started_cfg: LoadedConfig = config()
        self.gains_cfg: LoadedConfig = self.started_cfg
        self.limits_cfg: LoadedConfig = self.started_cfg
        self.pending: tuple[ReloadPlan, PendingCommand] | None = None
        self.deferred: ReloadPlan | None = None
        # changes that reopen the devices: `pamd run` can restart in place (a
        # library daemon, a virtual run cannot, and such a reload is refused)
        self.restart_in_place = False
        self.handover: str | None = None  # the changes a restart waiting for IDLE applies
        self.handing_over = False  # the loop was asked to end at an IDLE tick

    def service(self) -> None:
        """Every 50 ms: a verdict come back, a SIGHUP asked, the rig come to rest or
        IDLE for what waits for it."""
        if self.pending is not None:
            plan, pending = self.pending
            if not pending.done:
                return  # one reload at a time; a new SIGHUP waits for this verdict
            self.pending = None
            self._verdict(plan, pending.verdict)
        if self.requested:
            self.requested = False
            try:
                self._begin()
            except Exception:  # a reload must never take the running rig down
                log.exception("reload failed; still running on the config loaded before")
                self._finish()
        elif (self.handover is not None and not self.handing_over and self.pending is None
              and self.supervisor.state == State.IDLE):
            self.handing_over = True
            self.notifier.reloading()
            log.warning("the rig is IDLE: the loop ends holding the outputs, then pamd "
                        "restarts in place (%s)", self.handover)
            self.loop.request_handover(f"config reload: {self.handover}")
        elif (self.deferred is not None and self.pending is None
              and self.rig.at_rest()):  # not during a stop's ramp (issue 23)
            plan = self._plan(self.deferred.cfg)
            log.info("the rig is at rest: applying the deferred reload (%s)",
                     ", ".join(plan.idle) or "nothing left")
            self._submit(plan)

    def _plan(self, new: LoadedConfig) -> ReloadPlan:
        return plan_reload(self.started_cfg, self.gains_cfg, self.limits_cfg, new)

    def _begin(self) -> None:
        path = self.config().path
        self.notifier.reloading()
        log.info("SIGHUP: reloading %s", path)
        try:
            new = load_config(path, self.config_overrides)
            check_models_isolated(new)  # a model_file that does not fit is refused now
            # (read in a child process: a model's parse would stall the loop running here)
        except PamdError as exc:
            log.error("reload refused, still running on the config loaded before: %s", exc)
            self._finish()
            return
        except Exception as exc:  # noqa: BLE001 - a reload must never take the daemon down
            log.error("reload refused (%s: %s), still running on the config loaded before",
                      type(exc).__name__, exc)
            self._finish()
            return
        plan = self._plan(new)
        if self.handing_over:
            log.warning("reload: pamd is restarting in place already; the restarted daemon "
                        "reads %s again", path)
            return
        if self.handover is not None:
            log.info("reload: the restart in place waiting for IDLE is superseded by this "
                     "reload")
            self.handover = None
        if plan.restart:
            self._restart_when_idle(plan)
            return
        if self.deferred is not None:
            log.info("reload: the deferred reload is superseded by this one")
            self.deferred = None
        if not (plan.now or plan.idle):
            log.info("reload: %s has no changes to apply", path)
            self._finish()
            return
        self._submit(plan)

    def _restart_when_idle(self, plan: ReloadPlan) -> None:
        """Changes that reopen the devices: a restart in place once the rig is IDLE
        (`service`), or refused where this daemon cannot restart in place."""
        what = describe(plan.restart, self.started_cfg, plan.cfg)
        if not self.restart_in_place or self.loop.virtual:
            why = ("a virtual-clock run" if self.loop.virtual
                   else "this daemon is not `pamd run`")
            log.error("reload refused, still running on the config loaded before: %s "
                      "changed, which reopens the devices, and %s cannot restart in place: "
                      "needs a restart (systemctl restart pamd)", what, why)
            self._finish()
            return
        self.deferred = None  # the restart applies everything
        self.handover = what
        state = self.supervisor.state
        log.warning("reload: %s changed, which reopens the devices: pamd restarts in place "
                    "%s", what, "now (the rig is IDLE)" if state == State.IDLE else
                    f"once the rig is IDLE (it is {state.name}; `pamd cmd stop` ends what "
                    "runs)")
        if state != State.IDLE:
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

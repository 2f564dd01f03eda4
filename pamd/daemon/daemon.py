"""The daemon: a validated config turned into a running rig (drivers, controller,
loop thread), with a thread-safe way in (commands) and out (status, summary).

The loop runs in its own thread; the calling thread waits, prints the loop's
notices, saves datums changed by home/tare, and handles signals.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.daemon.io_session import IoParts, IoSession, RecordingRequest
from pamd.daemon.service.keeper import ServiceKeeper
from pamd.daemon.service.notify import Notifier
from pamd.daemon.service.riglock import RunLocks
from pamd.daemon.service.state import calibration_path, state_paths
from pamd.drivers.safe_outputs import push_safe_outputs
from pamd.loop.commands import Command, parse_command, prepare_command
from pamd.loop.commands.pending import PendingCommand
from pamd.loop.control.controller import RigController
from pamd.loop.control.feedforward import LoadedModel, load_models
from pamd.loop.control.summary import LocalMailbox, SummarySink
from pamd.loop.devices.bindings import Rig
from pamd.loop.devices.datum_file import load_calibration, save_calibration
from pamd.loop.experiment.plan import Plan
from pamd.loop.loop import Loop
from pamd.loop.safety import Transition
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused
from pamd.wire.net_spec import TelemetryRequest
from pamd.wire.tick import State, TickLayout
from pamd.wire.verbs.args import args_for_record

log = logging.getLogger("pamd")


@dataclass(frozen=True)
class _PlanArgs:
    plan_file: str
    start_step: int
    plan: Plan


class Daemon:
    """Owns one rig run. `start()`, then `command()`/`status()`, then `stop()` and
    `wait()`; `close()` releases the drivers."""

    def __init__(self, cfg: LoadedConfig, note: str = "",
                 recording: RecordingRequest | None = None, *, state_dir: str | None = None,
                 notifier: Notifier | None = None,
                 config_overrides: JsonObject | None = None,
                 telemetry: TelemetryRequest | None = None,
                 models: Mapping[str, LoadedModel] | None = None) -> None:
        """`models`: each muscle's inverse model, loaded; by default the daemon loads
        the config's `model_file`s (`load_models`: a ConfigError before anything opens).
        `state_dir` overrides the config's (see pamd.daemon.service.state: where the fault,
        the safe outputs and the datums are kept, if anywhere); `notifier`
        talks to systemd (the CLI passes `Notifier.from_environ()`);
        `config_overrides` are re-applied when the config is reloaded (SIGHUP);
        `telemetry` asks for Zenoh telemetry and commands as the config's
        `telemetry` section says (None: off; `pamd run` asks unless --no-telemetry)."""
        self.state = state_paths(cfg, state_dir)
        # the datums' file as this run keeps it (the state directory's by default)
        self.calibration_path = calibration_path(cfg, self.state)
        cfg = dataclasses.replace(cfg, calibration_path=self.calibration_path)
        self.cfg = cfg
        self.note = note
        self.calibration = load_calibration(cfg.calibration_path)
        self.rig = Rig(cfg, self.calibration)
        self.layout = TickLayout([m.name for m in cfg.rig.muscles])
        self.summary = SummarySink(self.layout)
        self.mailbox = LocalMailbox()
        self.ctrl = RigController(cfg, self.rig, self.summary, self.calibration,
                                  load_models(cfg) if models is None else models)
        self.summary.follow_cycles(self.ctrl.muscles)  # tracking after the first cycle
        self.loop = Loop(cfg, self.ctrl, self.mailbox)
        # the io process (MCAP recording, Zenoh telemetry): its sink goes downstream of
        # the summary. It gets the parts it uses, not the daemon.
        self.io = IoSession.attach(
            IoParts(lambda: self.cfg, note, self.layout, self.calibration, self.ctrl,
                    self.loop, self.summary, self.mailbox), recording, telemetry)
        self.transitions: deque[Transition] = deque(maxlen=1000)
        self.ctrl.listeners.append(self.transitions.append)
        self._thread: threading.Thread | None = None
        self.end_on_fault = False  # start(end_on_fault=...)
        self.error: BaseException | None = None
        # systemd notify, the latched fault and safe outputs kept across restarts, reload
        self.keeper = ServiceKeeper(self.ctrl, self.loop, self.mailbox.put, lambda: self.cfg,
                                    self._apply_config, self.state, notifier,
                                    config_overrides)
        self.keeper.restore()
        # what this run opens, one daemon at a time each (its drivers' ports, devices and
        # buses, its state directory; a simulation: nothing): taken by start() before
        # anything opens, released by close()
        claims = [c for drv in self.rig.drivers.values() for c in drv.claims()]
        if self.state is not None:
            claims.append(self.state.claim)
        self.locks = RunLocks(claims, cfg.rig.rig_id)
        self._unsaved_said = False

    def _apply_config(self, cfg: LoadedConfig) -> None:
        """A reloaded config, now in force (the keeper's reload)."""
        self.cfg = cfg

    # -- life cycle -------------------------------------------------------------------
    def start(self, duration_s: float | None = None, stop_when_profile_done: bool = False,
              end_on_fault: bool = False) -> None:
        """Run the loop in its thread until `stop()`, `duration_s` or, with
        `stop_when_profile_done`, the end of the profile's cycles. With `end_on_fault`, a
        latched fault or emergency stop ends the run too (`service()` asks for the stop:
        the loop returns once the safe state holds, every valve command at its safe
        pressure); without it the rig holds its safe state until a reset or a stop."""
        self.end_on_fault = end_on_fault
        # a declared load the force at rest disagrees with: a run that ends on a fault
        # refuses to start (nothing written); one that stays up takes the larger load
        self.ctrl.refuse_wrong_load = end_on_fault
        try:
            self.locks.acquire()  # RigBusy (what is held, by whom) before anything opens
            if self.io is not None:
                self.io.start()  # refuses (RecordingError) before anything opens or moves
            self.rig.open(self.loop.clock)
        except BaseException:
            if self.io is not None:
                self.io.discard()  # its shared memory and process: nothing left behind
            self.locks.release()
            raise
        push_safe_outputs(self.ctrl)  # what modules with a comm watchdog fall back to
        self.keeper.started()  # ... and what `pamd safe-outputs` replays
        self._thread = threading.Thread(
            target=self._run, args=(duration_s, stop_when_profile_done), name="pamd-loop",
            daemon=True)
        self._thread.start()

    def _run(self, duration_s: float | None, stop_when_done: bool) -> None:
        try:
            self.loop.run(duration_s, stop_when_done)
        except BaseException as exc:  # reported by wait(); the rig is closed by close()
            self.error = exc

    def stop(self, reason: str) -> None:
        self.loop.request_stop(reason)
        if self.io is not None:
            self.io.stopping(reason)  # liveliness token withdrawn, new commands refused
        self.keeper.stop_requested(reason)

    def request_reload(self) -> None:
        """Read the config again at the next `service()` (SIGHUP; any thread)."""
        self.keeper.reload_requested = True

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def wait(self, timeout_s: float | None = None, poll_s: float = 0.05) -> bool:
        """Wait for the loop to end (True) or the timeout (False), meanwhile printing
        notices and transitions and saving changed datums."""
        assert self._thread is not None
        waited = 0.0
        while self._thread.is_alive():
            self._thread.join(poll_s)
            self.service()
            waited += poll_s
            if timeout_s is not None and waited >= timeout_s:
                return False
        self.service()
        return True

    def service(self) -> None:
        """Housekeeping outside the loop's thread. Each share that holds the interpreter
        lock for long (the keeper's files and watchdog, the status snapshot) starts in
        the loop's slack, after a tick (`Loop.until_slack`), not at a wake-up."""
        sup = self.ctrl.supervisor
        if self.end_on_fault and sup.latched and self.loop.stop_requested is None:
            self.stop(f"{sup.state.name.lower()}: {sup.fault_reason}")
        while self.loop.notices:
            log.warning(self.loop.notices.popleft())
        while self.transitions:
            tr = self.transitions.popleft()
            level = logging.ERROR if tr.new in (State.FAULT, State.ESTOP) else logging.INFO
            log.log(level, "%s -> %s: %s", tr.old.name, tr.new.name, tr.reason)
        if self.ctrl.take_calibration_dirty():
            if self.calibration_path is not None:
                save_calibration(self.calibration, self.calibration_path)
            elif not self._unsaved_said:
                self._unsaved_said = True
                log.warning("the new home/tare datums hold for this run only: it keeps "
                            "no state (a simulation); --state-dir DIR (or state_dir, or "
                            "calibration_file in the config) keeps them")
        loop = self.loop
        loop.until_slack()
        self.keeper.service()
        if self.io is not None:
            loop.until_slack()
            self.io.service()  # telemetry: status snapshot, collect/model commands

    def close(self) -> None:
        self.keeper.close()  # STOPPING=1 if not yet sent; the fault file up to date
        if self.io is not None:
            self.io.close(self.result())  # finalises the file with the run summary
        self.rig.close()
        self.summary.close()
        self.locks.release()  # after the drivers let go of the hardware

    # -- commands and status -------------------------------------------------------------
    def submit(self, verb: str, payload: JsonObject | None = None,
               sender: str = "local") -> PendingCommand:
        """Queue a command for the loop without waiting. Commands queued before
        `start()` are applied on the first tick after the sensors are read."""
        pending = PendingCommand()
        try:
            cmd = parse_command(verb, payload, sender=sender, reply=pending.set)
            cmd = prepare_command(cmd, self.cfg)  # file I/O (model) here, not in the loop
        except CommandRefused as exc:
            pending.set({"ok": False, "error": str(exc)})
        except Exception as exc:  # the daemon never dies of a request
            log.exception("%s command", verb)
            verdict = {"ok": False, "error": f"{verb}: refused: it failed while being "
                       f"prepared ({exc.__class__.__name__}); the daemon goes on"}
            self.summary.event(self.ctrl.now, "command", {
                "verb": verb, "args": args_for_record(payload), "sender": sender,
                "by": "daemon", **verdict})
            pending.set(verdict)
        else:
            self.mailbox.put(cmd)
        return pending

    def start_plan(self, plan: Plan, plan_file: str, start_step: int = 0) -> PendingCommand:
        """Queue an experiment plan (already read and checked against this rig)."""
        pending = PendingCommand()
        args = _PlanArgs(plan_file=plan_file, start_step=start_step, plan=plan)
        self.mailbox.put(Command("collect", args, pending.set))
        return pending

    def command(self, verb: str, payload: JsonObject | None = None,
                timeout_s: float = 5.0, sender: str = "local") -> JsonObject:
        """Send a command to the loop and wait for its verdict."""
        return self.submit(verb, payload, sender).result(timeout_s)

    def wait_for_state(self, states: tuple[State, ...], timeout_s: float = 5.0) -> State:
        """Block until the supervisor is in one of `states` (or the timeout)."""
        done = threading.Event()
        waited = 0.0
        while self.ctrl.supervisor.state not in states and self.alive and waited < timeout_s:
            done.wait(0.005)
            waited += 0.005
            self.service()
        return self.ctrl.supervisor.state

    def result(self) -> JsonObject:
        """The run summary (`pamd run --json`), its keys declared in pamd.wire.declare.summary_keys
        (docs/run-summary.md)."""
        t = self.loop.timing.summary()
        sup = self.ctrl.supervisor
        return {
            "rig_id": self.cfg.rig.rig_id,
            "clock": self.loop.clock_name,
            "rate_hz": self.cfg.rig.loop.rate_hz,
            "ticks": t.ticks,
            "duration_s": t.ticks * self.cfg.period_s,
            "overruns": t.overruns,
            "stalls": self.loop.stalls.summary(),
            "lost_records": self.loop.lost_records,
            "wake_latency_us": {"p50": t.wake_p50_us, "p99": t.wake_p99_us, "max": t.wake_max_us},
            "compute_us": {"p50": t.compute_p50_us, "p99": t.compute_p99_us,
                           "max": t.compute_max_us},
            "loads_kg": {m.name: m.load_kg for m in self.ctrl.muscles},
            "tracking": self.summary.tracking(),
            # the model's watch: its inputs off its training domain, faded, oscillating
            "feedforward": {m.name: m.feedforward_report() for m in self.ctrl.muscles},
            "valve_switches": {m.name: m.actuation.switches() for m in self.ctrl.muscles},
            "faults": list(sup.faults),
            "final_state": sup.state.name,
            "outputs": {m.name: {"valve_cmd_bar": m.valve_cmd_bar,
                                 "safe_pressure_bar": m.safe_pressure_bar}
                        for m in self.ctrl.muscles},
            "stop_reason": self.loop.stopped_reason,
            # each driver's counters (retries, timeouts, reconnects, ...) and its last
            # errors: what a fault came from
            "drivers": {name: {"counters": h.counters, "errors": getattr(h, "errors", [])[-3:]}
                        for name, h in ((n, d.health()) for n, d in self.rig.drivers.items())},
            "realtime": {"applied": self.loop.rt.applied, "refused": self.loop.rt.warnings},
            "recording": self.io.result() if self.io is not None and self.io.recording
            else None,
            "telemetry": self.io.telemetry() if self.io is not None else None,
        }

"""The fixed-rate loop: absolute deadlines on the monotonic clock (or a virtual
clock that runs as fast as possible, or a DAQ card's sample clock), per-tick timing,
overrun handling, stall detection (`pamd.loop.stalls`: an event and a warning, FAULT only
past what the outputs hold by themselves; samples that aged during a stall are
excused), garbage collection only in slack time, commands once per tick.

`loop.clock: daq`: the card's sample clock paces the loop (`pamd.drivers.SampleClock`,
the one driver whose `sample_clock()` gives one): each tick waits for the next sample
instead of the OS timer and runs at its edge; the sample clocks that went by unticked
(late samples the card reported, samples the loop was too late for) count as overruns,
are said and skipped like the OS clock's missed periods. If no sample comes within
`sample_grace_s` of its due time (two periods, at least half `loop.stall_timeout_s`:
the device removed, its server gone), the OS clock stands in until samples return, so
the rig still reaches its safe state.

The loop's thread does no I/O: notices for the operator go into `notices`, which
another thread prints.
"""

from __future__ import annotations

import gc
import math
import sys
import threading
import time
from array import array
from collections import deque
from collections.abc import Callable

from pamd.config.loader import LoadedConfig
from pamd.drivers import SampleClock
from pamd.loop.commands import apply_command
from pamd.loop.control.controller import RigController
from pamd.loop.rt import RealtimeSession
from pamd.loop.stalls import StallWatch, stall_limit
from pamd.loop.tick_timing import TickTiming
from pamd.wire.tick import I_COMPUTE, I_LOST, I_OVERRUNS, I_WAKE, Mailbox, State

MAX_COMMANDS_PER_TICK = 4
_STARTING = State.STARTING  # (tick_once's: no lookup on the enum class every tick)
COMMAND_BUDGET_FRACTION = 0.3  # of the period: commands after the first wait past it
SAFE_STATE_DEADLINE_S = 30.0
GC_EVERY_TICKS = 200
GIL_SWITCH_FRACTION = 0.1
#: Another thread's housekeeping starts this far into a period (`Loop.until_slack`):
#: after the tick (woken ~30 us late, ~100 us of compute here, its p99 ~250 us), in
#: the slack before the next wake-up.
SLACK_AT_FRACTION = 0.3
#: loop.clock daq: a sample this many periods past its due time, and half the stall
#: timeout, is missing (the OS clock stands in): a sample's reads may take most of a
#: period on a busy host, and a gap the stall check calls normal is no device gone
SAMPLE_GRACE_PERIODS = 2.0
#: ... and the first, which may wait for the device's tasks to start
FIRST_SAMPLE_S = 0.2


class VirtualClock:
    """Time that only moves when the loop moves it: one period per tick."""

    def __init__(self, start_s: float = 0.0) -> None:
        self.t = start_s

    def __call__(self) -> float:
        return self.t


class CommandDispatch:
    """How commands reach the controller: at most MAX_COMMANDS_PER_TICK a tick, and
    after the first none once the tick has spent its command budget (perf_counter
    `until`): a burst waits its turn in the mailbox (each reply still waits for its
    verdict), it never makes the tick late. Nothing a command does can end the loop:
    `apply_command` turns any failure into a refusal, and a failing reply or mailbox
    is counted and noticed, not raised."""

    def __init__(self, mailbox: Mailbox, notices: deque[str]) -> None:
        self.mailbox = mailbox
        self.notices = notices
        self.faults = 0  # a mailbox or reply that raised

    def take(self, ctrl: RigController, until: float) -> None:
        perf = time.perf_counter
        for n in range(MAX_COMMANDS_PER_TICK):
            if n and perf() > until:
                return
            try:
                cmd = self.mailbox.poll()
            except Exception as exc:
                self._fault("the command mailbox", exc)
                return
            if cmd is None:
                return
            verdict = apply_command(ctrl, cmd)
            if cmd.reply is not None:
                try:
                    cmd.reply(verdict)
                except Exception as exc:
                    self._fault(f"the reply to {cmd.verb}", exc)

    def _fault(self, what: str, exc: Exception) -> None:
        self.faults += 1
        self.notices.append(f"commands: {what} failed ({exc.__class__.__name__}: {exc}); "
                            f"{self.faults} so far, the loop goes on")


def tick_once(ctrl: RigController, intake: CommandDispatch, now_s: float, dt_s: float,
              commands_until: float) -> array[float]:
    """One tick, as both `Loop` and `pamd.loop.harness.Harness` run it: the waiting commands
    first (held in the mailbox until the sensors are read: none while STARTING), then
    the controller's tick. Returns the tick record."""
    if ctrl.supervisor.state != _STARTING:
        intake.take(ctrl, commands_until)
    return ctrl.tick(now_s, dt_s)


class Loop:
    """Runs `controller.tick` at a fixed rate until stopped, then reaches the safe
    state before returning."""

    def __init__(self, cfg: LoadedConfig, controller: RigController, mailbox: Mailbox) -> None:
        self.cfg = cfg
        self.ctrl = controller
        self.period_s = cfg.period_s
        lc = cfg.rig.loop
        self.virtual = lc.clock == "virtual"
        self.clock_name: str = lc.clock  # real, virtual or daq (status, summary)
        self.skip_overruns = lc.overrun_policy == "skip"
        self.stalls = StallWatch(lc.stall_timeout_s, stall_limit(cfg.rig))
        self.stall_s = self.stalls.check_s  # a longer gap with no tick completed: a stall
        self.clock: Callable[[], float] = VirtualClock() if self.virtual else time.monotonic
        self.pacer: SampleClock | None = (
            paced_by(controller, cfg) if lc.clock == "daq" else None)
        self.clock_gaps = 0  # loop.clock daq: ticks the OS clock paced (no sample came)
        self.sample_grace_s = max(SAMPLE_GRACE_PERIODS * self.period_s,
                                  0.5 * lc.stall_timeout_s)
        # loop.clock daq: when each notice (gap, missed) was last said (at most once a second)
        self._said_gap_s = self._said_missed_s = -math.inf
        self.timing = TickTiming()
        self.notices: deque[str] = deque(maxlen=256)
        self.lost_records = 0
        self.rt = RealtimeSession()
        self.intake = CommandDispatch(mailbox, self.notices)
        self._stop_reason: str | None = None
        self.stopped_reason = ""
        self._handover_reason: str | None = None
        self.handed_over = False  # ended at an IDLE tick, outputs held (restart in place)
        self.running = False
        self.last_tick_done = math.nan  # monotonic time of the last completed tick
        self.next_deadline = math.nan  # the clock's time of the next tick (`until_slack`)
        self._idle: Callable[[], bool] | None = None  # see `stand_still_while`
        self._woken = threading.Condition()
        # one run's state (`_run`): when it ends, when its stop began, the last overrun
        # said, whether it ran a profile, the drivers' samples' age excused and until when
        self._end_t = self._stopping_since = self._settling_since = math.inf
        #: a stop's settle: the command given this long to reach the safe pressure
        #: once the setpoint is there (`_stopped`)
        self.settle_s = cfg.rig.safety.tracking_time_s
        self._last_warn = -math.inf
        self._saw_running = False
        self._excuse = self._excused_until = 0.0

    @property
    def mailbox(self) -> Mailbox:
        return self.intake.mailbox

    @mailbox.setter
    def mailbox(self, mailbox: Mailbox) -> None:
        """Another mailbox (the io process adds its own), before `run`."""
        self.intake.mailbox = mailbox

    @property
    def command_faults(self) -> int:
        """Mailboxes or replies that raised (see `CommandDispatch`)."""
        return self.intake.faults

    @property
    def stop_requested(self) -> str | None:
        """The reason of a requested stop, or None."""
        return self._stop_reason

    @property
    def stall_fault_s(self) -> float:
        """A stall longer than this latches FAULT."""
        return self.stalls.limit.fault_s

    def set_stall_limits(self, cfg: LoadedConfig) -> None:
        """A reload's `loop.stall_timeout_s` / `stall_fault_s` and the limit its
        actuation allows (the main thread reads them), and its `safety.tracking_time_s`
        (a stop's settle, `settle_s`)."""
        self.settle_s = cfg.rig.safety.tracking_time_s
        self.stalls.limit = stall_limit(cfg.rig)
        self.stalls.timeout_s = cfg.rig.loop.stall_timeout_s
        self.stall_s = self.stalls.check_s
        self.sample_grace_s = max(SAMPLE_GRACE_PERIODS * self.period_s,
                                  0.5 * cfg.rig.loop.stall_timeout_s)

    def stand_still_while(self, idle: Callable[[], bool]) -> None:
        """On the virtual clock, time stands still at the start of any tick at which
        `idle()` (asked in the loop's thread) is true, until it is not (asked again at
        `wake()`, and every 50 ms) or a stop is requested: for a thread that drives the
        rig step by step (commissioning), so that how many ticks pass between its steps
        does not depend on how fast that thread is (a virtual run stays deterministic).
        Before `run`. Ignored on the real clock, where time does not stand still."""
        if self.virtual:
            self._idle = idle

    def wake(self) -> None:
        """Ask a loop that stands still (`stand_still_while`) whether it may go on
        (any thread but a signal handler's)."""
        with self._woken:
            self._woken.notify_all()

    def _stand_still(self, idle: Callable[[], bool]) -> None:
        with self._woken:
            while self._stop_reason is None and idle():
                self._woken.wait(0.05)

    def until_slack(self) -> None:
        """Sleep (another thread: the daemon's main thread, before each share of its
        housekeeping) until SLACK_AT_FRACTION of a period past the loop's next deadline,
        where that tick is done: what the caller does next then holds the interpreter
        lock in the loop's slack, not at its wake-up. The loop's thread, woken, must
        take the lock back from whichever thread holds it, which lets go only at its
        next switch interval (a tenth of a period), or after a C call that holds it
        (a status snapshot's JSON encoding): the main thread's 0.3-0.4 ms of status,
        persistence and watchdog every 50 ms, at random phase, met 0.6-0.8 % of the
        wake-ups, the 99th percentile's tail (bench/loop_latency_vs_cyclictest.py).
        Returns at once on the virtual clock (no wake-ups) or while the loop is not
        running; never sleeps longer than two periods."""
        if self.virtual or not self.running:
            return
        period = self.period_s
        wait = self.next_deadline + SLACK_AT_FRACTION * period - time.monotonic()
        if wait > 0.0:
            time.sleep(wait if wait < 2.0 * period else 2.0 * period)

    def request_stop(self, reason: str) -> None:
        """Ask the loop to reach the safe state and return (any thread)."""
        if self._stop_reason is None:
            self._stop_reason = reason

    def request_handover(self, reason: str) -> None:
        """Ask the loop to end at the next tick that finds the rig at rest (IDLE, no
        profile, a ramp to the safe state completed), without ramping to the safe
        state: the outputs hold what they hold, for a daemon that restarts in place (a
        reload that reopens the drivers). A stop requested before or meanwhile wins
        (any thread)."""
        if self._handover_reason is None:
            self._handover_reason = reason

    def _stalled(self, gap_s: float) -> None:
        """A stall that ended: an event, a count and a warning; FAULT past the limit."""
        ctrl, watch = self.ctrl, self.stalls
        fault = watch.record(gap_s)
        text = watch.describe(gap_s)
        ctrl.sink.event(ctrl.now, "stall", {
            "gap_ms": round(1000 * gap_s, 1), "count": watch.count, "fault": fault,
            "fault_ms": round(1000 * watch.limit.fault_s, 1)})
        if fault:
            if not ctrl.supervisor.latched:
                ctrl.supervisor.fault(ctrl.now, text)
        else:
            self.notices.append(f"{text}; not a fault, the loop goes on")

    def run(self, duration_s: float | None = None, stop_when_profile_done: bool = False) -> None:
        ctrl = self.ctrl
        switch_interval = sys.getswitchinterval()
        if not self.virtual:
            self.rt.apply(self.cfg.rig.loop.realtime, self.notices.append)
        # Driver threads share the interpreter lock; when the loop wakes, whoever holds
        # it must let go within a fraction of a period, not the default 5 ms. On the
        # virtual clock the loop never sleeps: the daemon's main thread (status, the
        # commands' files and collections) takes the lock back after each of its file
        # operations, and at 5 ms a wait a collect's few hundred of them took seconds.
        sys.setswitchinterval(min(switch_interval, GIL_SWITCH_FRACTION * self.period_s))
        gc.collect()
        gc.freeze()
        gc.disable()
        try:
            self._run(ctrl, duration_s, stop_when_profile_done)
        finally:
            if self.pacer is not None:
                self.pacer.detach()  # its driver writes on without waiting for ticks
            sys.setswitchinterval(switch_interval)
            gc.enable()
            gc.unfreeze()
            self.rt.close()
            self.running = False

    def _run(self, ctrl: RigController, duration_s: float | None, stop_when_done: bool) -> None:
        """Tick until stopped and the safe state holds (or a hand-over): wait for the
        deadline, take the waiting commands and tick, account for the tick, judge the
        run's end, find the next deadline; garbage collected only in slack time."""
        period = self.period_s
        timing = self.timing
        mono = time.monotonic
        start = self.clock()
        ctrl.start(start)
        self._end_t = math.inf if duration_s is None else start + duration_s
        self._stopping_since = self._settling_since = math.inf
        self._last_warn = -math.inf
        self._saw_running = False
        self._excuse = self._excused_until = 0.0
        self.running = True
        self.last_tick_done = mono()
        # virtual clock: deterministic, so no budget by the machine's speed
        command_budget_s = math.inf if self.virtual else COMMAND_BUDGET_FRACTION * period
        wait = self._wait_virtual if self.virtual else self._wait_real
        relaxed = self.virtual or self.pacer is not None  # no late deadline to judge
        intake = self.intake
        if self.pacer is not None:
            self.pacer.attach()
        next_t, dt = start, period
        self.next_deadline = start
        while True:
            next_t, dt, wake, t_wake = wait(next_t, dt)
            # commands (held until the sensors are read), then the tick
            rec = tick_once(ctrl, intake, next_t, dt, t_wake + command_budget_s)
            self._account(rec, wake, t_wake)
            if self._ends(ctrl, next_t, stop_when_done):
                break
            next_t += period
            dt = period
            if not relaxed:
                next_t, dt = self._late(next_t)
            self.next_deadline = next_t
            if timing.ticks % GC_EVERY_TICKS == 0 and (
                    self.virtual or next_t - mono() > 0.5 * period):
                gc.collect(0)

    def _wait_virtual(self, next_t: float, dt: float) -> tuple[float, float, float, float]:
        """The virtual clock moved to the deadline (standing still first while the
        commissioning thread says so: `stand_still_while`). Returns (the tick's time, its
        dt, its wake-up lateness, 0 here, the perf_counter at wake-up)."""
        idle = self._idle
        if idle is not None and self._stop_reason is None and idle():
            self._stand_still(idle)
        vclock = self.clock
        assert isinstance(vclock, VirtualClock)
        vclock.t = next_t
        return next_t, dt, 0.0, time.perf_counter()

    def _wait_real(self, next_t: float, dt: float) -> tuple[float, float, float, float]:
        """Sleep to the deadline (or, `loop.clock: daq`, wait for the sample); a wake-up
        periods late skips the missed periods (`overrun_policy: skip`); the drivers'
        samples excused a stall's age. Returns as `_wait_virtual`."""
        mono = time.monotonic
        pacer = self.pacer
        if pacer is not None:  # loop.clock daq: the tick at the sample's edge
            next_t, dt = self._sample_due(pacer, next_t, dt)
            now = mono()
        else:
            now = mono()
            if now < next_t:
                time.sleep(next_t - now)
                now = mono()
        wake = now - next_t
        if wake >= self.period_s and self.skip_overruns and pacer is None:
            next_t, dt = self._skip_missed(wake, next_t, dt)
        t_wake = time.perf_counter()
        self._excuse_gap(now)
        return next_t, dt, wake, t_wake

    def _skip_missed(self, wake: float, next_t: float, dt: float) -> tuple[float, float]:
        """Woken periods late (the process got no CPU): this tick runs at the present
        deadline with dt over the whole gap, so a stepped plant and its samples' stamps
        agree (no jump "in 1 ms")."""
        period = self.period_s
        missed = int(wake / period)
        self.timing.overruns += missed
        next_t += missed * period
        dt += missed * period
        self._say_overrun(next_t, missed)
        return next_t, dt

    def _say_overrun(self, next_t: float, missed: int) -> None:
        if next_t - self._last_warn >= 1.0:  # at most once a second
            self._last_warn = next_t
            self.notices.append(f"overrun: {missed} period(s) missed "
                                f"({self.timing.overruns} so far)")

    def _excuse_gap(self, now: float) -> None:
        """A tick more than two periods after the last one: the drivers may have stalled
        with the loop, so their samples' age is excused for as long as the gap (a larger
        one stands until its own end); back to nothing once it is over."""
        period = self.period_s
        gap = now - self.last_tick_done
        if gap > 2.0 * period:
            if gap - period >= self._excuse or now > self._excused_until:
                self._excuse = gap - period
                self._excused_until = now + self.ctrl.excuse_stall(self._excuse)
        elif self._excuse and now > self._excused_until:
            self._excuse = 0.0
            self.ctrl.excuse_stall(0.0)

    def _account(self, rec: array[float], wake: float, t_wake: float) -> None:
        """The tick's timing into its record and histograms, the record to the sink (a
        lost one counted), the pacer told, a stall found by the time since the last."""
        compute = time.perf_counter() - t_wake
        timing = self.timing
        rec[I_WAKE] = wake
        rec[I_COMPUTE] = compute
        rec[I_OVERRUNS] = timing.overruns
        rec[I_LOST] = self.lost_records
        if not self.ctrl.sink.put(rec):
            self.lost_records += 1
        if self.pacer is not None:
            self.pacer.tick_done()  # the driver writes this tick's outputs
        timing.wake.add(wake)
        timing.compute.add(compute)
        timing.ticks += 1
        done = time.monotonic()
        if done - self.last_tick_done > self.stall_s and not self.virtual:
            self._stalled(done - self.last_tick_done)
        self.last_tick_done = done

    def _ends(self, ctrl: RigController, next_t: float, stop_when_done: bool) -> bool:
        """Whether the loop ends after this tick: a hand-over at rest, or a stop (the
        duration reached, a profile finished, a request) once the safe state holds or
        its deadline passed."""
        state = ctrl.supervisor.state
        if state == State.RUNNING:
            self._saw_running = True
        if self._stop_reason is None:
            if next_t >= self._end_t:
                self.request_stop("duration reached")
            elif stop_when_done and self._saw_running and state == State.IDLE:
                self.request_stop("profile finished")
        if self._handing_over(ctrl, state):
            return True
        if self._stop_reason is not None and self._stopping_since == math.inf:
            self._stopping_since = next_t
            self.stopped_reason = self._stop_reason
            ctrl.go_safe(f"{self._stop_reason}: ramping to the safe state")
        return self._stopping_since != math.inf and self._stopped(ctrl, next_t)

    def _stopped(self, ctrl: RigController, next_t: float) -> bool:
        """A stop under way has ended: the setpoints at the safe pressure and then the
        commands too, or `settle_s` after the setpoints got there
        (`rig_safe_state.commands_at_safe` says why), or the stop's deadline passed."""
        if next_t - self._stopping_since > SAFE_STATE_DEADLINE_S:
            return True
        if not ctrl.at_safe_state():
            self._settling_since = math.inf
            return False
        if self._settling_since == math.inf:
            self._settling_since = next_t
        return ctrl.commands_at_safe() or next_t - self._settling_since >= self.settle_s

    def _handing_over(self, ctrl: RigController, state: State) -> bool:
        """A hand-over asked for, no stop, the rig at rest (not during a ramp)."""
        if (self._handover_reason is not None and self._stop_reason is None
                and state == State.IDLE and ctrl.at_rest()):
            self.handed_over = True  # first: the main thread reads them in this order
            self.stopped_reason = self._handover_reason
            return True
        return False

    def _late(self, next_t: float) -> tuple[float, float]:
        """The real clock's next deadline already past (the tick ran late): the periods
        missed are overruns, skipped with `overrun_policy: skip` (then the next tick's dt
        spans them). Returns the next deadline and its dt."""
        period = self.period_s
        late = time.monotonic() - next_t
        if late <= 0.0:
            return next_t, period
        missed = int(late / period) + 1
        self.timing.overruns += missed
        dt = period
        if self.skip_overruns:
            next_t += missed * period
            dt = period * (missed + 1)
        self._say_overrun(next_t, missed)
        return next_t, dt

    def _sample_due(self, pacer: SampleClock, due_t: float, dt: float) -> tuple[float, float]:
        """loop.clock daq: wait for the next sample; returns the tick's time (its edge, or
        the OS clock's when none came: module docstring) and its dt. Missed sample
        clocks are overruns, skipped (a sample once gone cannot be ticked late)."""
        last_t = due_t - dt  # the previous tick's time
        grace_s = self.sample_grace_s if self.timing.ticks else FIRST_SAMPLE_S
        edge = pacer.wait(due_t + grace_s)
        while edge <= last_t:  # taken before the tick the OS clock ran: gone by unticked
            self.timing.overruns += 1
            edge = pacer.wait(due_t + grace_s)
        if edge != edge:
            self.clock_gaps += 1
            now = time.monotonic()
            if now - self._said_gap_s >= 1.0:
                self._said_gap_s = now
                self.notices.append(
                    f"no sample from {pacer.describe()} for {1000 * (now - last_t):.0f} ms: "
                    f"the OS clock paces the loop until it returns ({self.clock_gaps} ticks "
                    "so far)")
            return now, now - last_t
        missed = pacer.take_missed()
        if missed:
            self.timing.overruns += missed
            if edge - self._said_missed_s >= 1.0:
                self._said_missed_s = edge
                self.notices.append(f"overrun: {missed} sample clock(s) of "
                                    f"{pacer.describe()} went by unticked "
                                    f"({self.timing.overruns} so far)")
        return edge, edge - last_t


def paced_by(ctrl: RigController, cfg: LoadedConfig) -> SampleClock:
    """The sample clock that paces a `loop.clock: daq` loop: the one driver's that gives
    one (the config loader refuses another number)."""
    clocks = [c for d in ctrl.rig.drivers.values() if (c := d.sample_clock()) is not None]
    if len(clocks) != 1:
        raise ValueError(f"{cfg.path}: loop.clock daq needs one driver with a sample clock "
                         f"(a nidaqmx driver with timing hardware_timed), found {len(clocks)}")
    return clocks[0]

"""Timing keys bounded by physics, at load: a duration a check or a controller counts
in ticks cannot be shorter than the ticks it needs, and a wait for the rig cannot be
shorter than the rig's own response. Each refusal names the key, the bound and why.

* `safety.tracking_time_s`: the measured pressure answers a change of its command
  only after the plant's dead time, and settles (95 %) three lags later
  (`pamd.config.stability.Plant.settle_s`, on each proportional muscle's pressure
  plant: `control.plant`, stated or the default; on/off valves: three of their PWM
  loop's `onoff.response_s`): a tracking time shorter than that faults a healthy
  muscle on a fast change of command (a safe-state ramp at the e-stop slew); and never
  shorter than a period (two readings, not one).
* `safety.startup_timeout_s`: a healthy device delivers its first sample within its
  sample period (`sample_period_s`; none: the first poll) plus the delivery latency
  the rig declares (`safety.latency_margin_s`), so the start-up waits at least the
  slowest input's.
* `safety.plausibility.frozen_s`, `safety.plausibility.force_zero_s`: a reading
  repeats, or reads zero, over a span of at least one period (two readings): a
  shorter span judges one reading, its noise or its lateness.
* `loop.stall_fault_s`: a stall is a gap of at least two periods (as
  `loop.stall_timeout_s`).
* `control.position.incremental.sample_period_s`: the controller is sampled by the
  tick: at least one period.
* `control.position.ilc.resolution_s`: the learning's bins are allocated per cycle
  (`pamd.loop.control.ilc`), and one finer than the tick holds no reading of its own (it is
  read between its neighbours): at most `ILC_BINS_PER_TICK` bins a tick, or a cycle's
  bins grow without bound (1e-300 s: 10^301 of them).
* `muscles[].onoff.pwm_period_s`, `muscles[].onoff.position_period_s`: a PWM period
  resolves a duty cycle in ticks: at least two (one open, one closed).
"""

from __future__ import annotations

from pamd.config.gains import pressure_plant
from pamd.config.schema import RigConfig, SignalConfig, muscle_control
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.schema.engine import Context, line_at

#: The most learning bins a tick may hold (`control.position.ilc.resolution_s`).
ILC_BINS_PER_TICK = 10


def check_timing(rig: RigConfig, raw: JsonValue, ctx: Context) -> None:
    """Add an issue for each timing key shorter than its physics allows (module doc)."""
    period_s = 1.0 / rig.loop.rate_hz
    ticks = f"{1e3 * period_s:g} ms ticks at loop.rate_hz {rig.loop.rate_hz:g}"

    def need(path: str, value: float | None, least: float, why: str) -> None:
        if value is not None and value < least * (1.0 - 1e-9):
            ctx.add(line_at(raw, path), path, f"at least {_s(least)} ({why})", _s(value))

    s = rig.safety
    settle, who = _slowest_pressure_response(rig)
    need("safety.tracking_time_s", s.tracking_time_s, max(settle, period_s),
         f"the measured pressure answers a command after the plant's dead time and "
         f"settles in three lags more: {_s(settle)} on {who}; shorter faults a healthy "
         "muscle")
    slowest, signal = _slowest_input(rig)
    need("safety.startup_timeout_s", s.startup_timeout_s, max(slowest, period_s),
         f"a healthy device's first sample arrives within its sample period plus "
         f"safety.latency_margin_s: {_s(slowest)} for {signal}")
    for key in ("frozen_s", "force_zero_s"):
        need(f"safety.plausibility.{key}", getattr(s.plausibility, key), period_s,
             f"one of the {ticks}: a shorter span judges a single reading")
    need("loop.stall_fault_s", rig.loop.stall_fault_s, 2.0 * period_s,
         f"two {ticks}: a stall is a gap of at least two periods")
    pos = rig.control.position
    need("control.position.ilc.resolution_s", pos.ilc.resolution_s,
         period_s / ILC_BINS_PER_TICK,
         f"1/{ILC_BINS_PER_TICK} of one of the {ticks}: a finer bin holds no reading of "
         "its own, and a cycle's bins cost memory")
    need("control.position.incremental.sample_period_s", pos.incremental.sample_period_s,
         period_s, f"one of the {ticks}: the controller is sampled by the tick")
    for i, m in enumerate(rig.muscles):
        if m.actuation == "onoff":
            for key in ("pwm_period_s", "position_period_s"):
                need(f"muscles[{i}].onoff.{key}", getattr(m.onoff, key), 2.0 * period_s,
                     f"two {ticks}: a duty cycle needs a tick open and a tick closed")


def _slowest_pressure_response(rig: RigConfig) -> tuple[float, str]:
    """The longest time a muscle's pressure takes to answer a command step (95 %)."""
    worst, who = 0.0, "no muscle"
    for m in rig.muscles:
        if m.actuation == "onoff":
            t, how = 3.0 * m.onoff.response_s, "its PWM loop's response_s x 3"
        else:
            ctl = muscle_control(rig.control, m.control)
            t = pressure_plant(ctl).settle_s()
            how = "its pressure plant" + ("" if ctl.plant else ", the default")
        if t > worst:
            worst, who = t, f"muscle {m.name!r} ({how})"
    return worst, who


def _slowest_input(rig: RigConfig) -> tuple[float, str]:
    """The longest a healthy input takes to deliver its first sample."""
    worst, which = 0.0, "no input"
    for m in rig.muscles:
        for name in ("pressure", "force", "length"):
            sig: SignalConfig = getattr(m.signals, name)
            t = (sig.sample_period_s or 0.0) + rig.safety.latency_margin_s
            if t > worst:
                worst, which = t, f"{m.name}.{name}"
    return worst, which


def _s(value: float) -> str:
    return f"{value:.4g} s" if value >= 1.0 else f"{1e3 * value:.4g} ms"

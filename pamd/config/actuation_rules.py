"""The config rules of a muscle's actuation, checked with the rest of the config.

`actuation: proportional` (a pressure regulator): `signals.valve` is required, an
`inflate` signal is refused. `actuation: onoff` (seed 004's solenoid valves): both
`signals.inflate` and `signals.exhaust` are required, each on a *digital* output of
its driver (`pamd.drivers.Channel.digital`: the sim driver's NAME.inflate and
NAME.exhaust, a Modbus coil), `signals.valve` is refused, and the PWM period must
leave a valve the time to open and close within it. An exhaust assist
(`exhaust_assist_below_bar`) needs an exhaust valve beside the regulator. A simulated
muscle's sensors must sample within the timeout of the signal that reads them (a
device slower than its timeout is stale by construction), and a scheduled stall of the
loop's process needs the real clock (a virtual one does not move while the process is
stopped).
Every refusal names file, line and key.
"""

from __future__ import annotations

from collections.abc import Callable

from pamd.config.safety_schema import SafetyConfig
from pamd.config.schema import MuscleConfig, RigConfig, SignalConfig
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.schema.engine import Context, line_of

#: The sim driver's sensor options, per input signal: (sample period, latency).
_SIM_SENSORS = {"pressure": ("pressure_sample_period_s", "pressure_latency_s"),
                "force": ("force_sample_period_s", "force_latency_s"),
                "length": ("length_sample_period_s", "length_latency_s")}


def check_actuation(rig: RigConfig, node: JsonValue, digital: dict[str, set[str]],
                    ctx: Context) -> None:
    """The actuation rules for every muscle; `node` is the raw `muscles` list and
    `digital` the digital output channels per driver whose options are valid."""
    for i, m in enumerate(rig.muscles):
        item = node[i] if isinstance(node, list) and i < len(node) else {}
        sig_node = item.get("signals") or {}
        base = f"muscles[{i}]"
        if m.actuation == "proportional":
            _check_proportional(m, item, sig_node, base, ctx)
        else:
            _check_onoff(m, item, sig_node, base, digital, ctx)


def _check_proportional(m: MuscleConfig, item: JsonValue, sig_node: JsonValue, base: str,
                        ctx: Context) -> None:
    if m.signals.valve is None:
        ctx.add(line_of(sig_node) or line_of(item, "signals"), f"{base}.signals.valve",
                "the pressure regulator's setpoint output (actuation: proportional; for "
                "solenoid valves set actuation: onoff with signals.inflate and "
                "signals.exhaust)", "none")
    if m.exhaust_assist_below_bar is not None and m.signals.exhaust is None:
        ctx.add(line_of(item, "exhaust_assist_below_bar"), f"{base}.exhaust_assist_below_bar",
                "an exhaust valve to assist with (signals.exhaust), or no exhaust assist",
                f"{m.exhaust_assist_below_bar:g} bar without signals.exhaust")
    if m.signals.inflate is not None:
        ctx.add(line_of(sig_node, "inflate"), f"{base}.signals.inflate",
                "no inflate valve with actuation: proportional (a regulator fills the "
                "muscle; set actuation: onoff to drive solenoid valves)", "an inflate signal")


def _check_onoff(m: MuscleConfig, item: JsonValue, sig_node: JsonValue, base: str,
                 digital: dict[str, set[str]], ctx: Context) -> None:
    if m.exhaust_assist_below_bar is not None:
        ctx.add(line_of(item, "exhaust_assist_below_bar"), f"{base}.exhaust_assist_below_bar",
                "no exhaust assist with actuation: onoff (its PWM drives the exhaust valve)",
                f"{m.exhaust_assist_below_bar:g} bar")
    if m.signals.valve is not None:
        ctx.add(line_of(sig_node, "valve"), f"{base}.signals.valve",
                "no regulator setpoint with actuation: onoff (the inflate and exhaust valves "
                "fill and vent the muscle); remove it or set actuation: proportional",
                "a valve signal")
    for name, what in (("inflate", "the inflate valve (3/2 NC, supply -> muscle)"),
                       ("exhaust", "the exhaust valve (2/2 NC, muscle -> atmosphere)")):
        sig = getattr(m.signals, name)
        path = f"{base}.signals.{name}"
        if sig is None:
            ctx.add(line_of(sig_node) or line_of(item, "signals"), path,
                    f"{what}: actuation: onoff needs both signals.inflate and "
                    "signals.exhaust", "none")
            continue
        outs = digital.get(sig.driver)
        if outs is not None and sig.channel not in outs:
            names = ", ".join(sorted(outs)) or "none"
            ctx.add(line_of(sig_node.get(name) or {}, "channel"), f"{path}.channel",
                    f"a digital output of driver {sig.driver!r} for {what} (a solenoid "
                    f"valve is open or closed; digital outputs: {names})", repr(sig.channel))
    o = m.onoff
    switching = o.valve_on_delay_s + o.valve_off_delay_s
    if o.pwm_period_s < switching:
        ctx.add(line_of(item.get("onoff") or {}, "pwm_period_s") or line_of(item, "onoff"),
                f"{base}.onoff.pwm_period_s",
                f"at least the valves' switching times, valve_on_delay_s + "
                f"valve_off_delay_s = {switching:g} s (a valve must open and close within "
                "a period)", f"{o.pwm_period_s:g} s")


def check_sim_sample_periods(rig: RigConfig, node: JsonValue, ctx: Context,
                             timeout_of: Callable[[SignalConfig, SafetyConfig], float]
                             ) -> None:
    """A simulated muscle's sensor whose sample period plus latency (plus a bursty
    link's hold) exceeds the timeout
    of the signal that reads it (`timeout_of`, the loader's stale age) is refused, at
    the sim driver's option; `node` is the raw `drivers` list."""
    sims = {d.name: (i, d) for i, d in enumerate(rig.drivers)
            if d.type == "sim" and hasattr(d.options, "muscles")}
    if not sims:
        return
    drivers_node = node if isinstance(node, list) else []
    for m in rig.muscles:
        for signal, (period_key, latency_key) in _SIM_SENSORS.items():
            sig = getattr(m.signals, signal)
            if sig.driver not in sims:
                continue
            k, drv = sims[sig.driver]
            sim_name, _, sensor = sig.channel.rpartition(".")
            for j, sm in enumerate(drv.options.muscles):
                if sm.name != sim_name or sensor != signal:
                    continue
                age_s = (getattr(sm, period_key) + getattr(sm, latency_key)
                         + getattr(sm, f"{signal}_burst_s", 0.0))  # a held link ages it
                timeout = timeout_of(sig, rig.safety)
                if age_s > timeout:
                    opts = (drivers_node[k].get("options") or {}) if k < len(drivers_node) else {}
                    mnode = (opts.get("muscles") or [{}])
                    mnode = mnode[j] if j < len(mnode) and isinstance(mnode[j], dict) else {}
                    ctx.add(line_of(mnode, period_key) or line_of(mnode),
                            f"drivers[{k}].options.muscles[{j}].{period_key}",
                            f"a sample period plus latency (and burst hold) within the timeout of "
                            f"muscle {m.name!r}'s {signal} signal ({timeout:g} s): a slower "
                            "device is stale by construction; raise the signal's timeout_s",
                            f"{age_s:g} s")


def check_sim_stalls(rig: RigConfig, node: JsonValue, ctx: Context) -> None:
    """A sim driver's scheduled `stall` (signal loop) cannot happen with a virtual
    clock: refused at its `failure` (or its old key `kind`); `node` is the raw `drivers` list."""
    if rig.loop.clock != "virtual":
        return
    drivers_node = node if isinstance(node, list) else []
    for k, d in enumerate(rig.drivers):
        faults = getattr(d.options, "faults", ()) if d.type == "sim" else ()
        for j, f in enumerate(faults):
            if getattr(f, "failure", None) != "stall":
                continue
            dnode = drivers_node[k] if k < len(drivers_node) else {}
            opts = (dnode.get("options") or {}) if isinstance(dnode, dict) else {}
            fnode = (opts.get("faults") or [{}])
            fnode = fnode[j] if j < len(fnode) and isinstance(fnode[j], dict) else {}
            key = "kind" if "kind" in fnode else "failure"  # the key the file gives
            ctx.add(line_of(fnode, key) or line_of(fnode), f"drivers[{k}].options.faults[{j}]"
                    f".{key}", "loop.clock real for a stall of the loop's process (a virtual "
                    "clock does not move while the process is stopped, so the loop would "
                    "never see it)", "stall with loop.clock virtual")

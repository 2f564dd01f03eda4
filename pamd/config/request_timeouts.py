"""A driver's request timeout against the timeouts of the signals it reads.

What must hold: one lost reply (noise on the line, a device busy for a moment) must
not make a healthy signal stale. A driver that re-sends an unanswered request
(`pamd.drivers.modbus`) delivers the next fresh value up to `lost_reply_s()` later
than usual (its request timeout, the retry's round trip and its poll period), and
that value is up to one sample period old when it is taken. If that sum reaches the
signal's stale age, every lost reply faults the rig: the config is refused at the
driver's `timeout_s` with the largest value that fits.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from pamd.config.safety_schema import SafetyConfig
from pamd.config.schema import InputSignal, RigConfig, SignalConfig
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.schema.engine import Context, line_of


def check_request_timeouts(rig: RigConfig, node: JsonValue, lost_reply: dict[str, float],
                           ctx: Context,
                           timeout_of: Callable[[SignalConfig, SafetyConfig], float],
                           inputs: Sequence[InputSignal]) -> None:
    """Refuse a driver whose `lost_reply` (seconds, by driver name) plus an input
    signal's sample period reaches that signal's stale age (`timeout_of`); `node` is
    the raw `drivers` list, `inputs` every input signal (`loader.input_signals`: the
    muscles' and the safety chain's, whose e-stop input going stale opens the chain)."""
    drivers_node = node if isinstance(node, list) else []
    index = {d.name: k for k, d in enumerate(rig.drivers)}
    worst: dict[str, tuple[float, str, float]] = {}  # driver: (slack, signal, timeout)
    for _, label, sig, _ in inputs:
        if sig.driver not in lost_reply:
            continue
        timeout = timeout_of(sig, rig.safety)
        slack = timeout - (sig.sample_period_s or 0.0) - lost_reply[sig.driver]
        if slack <= 0.0 and (sig.driver not in worst or slack < worst[sig.driver][0]):
            worst[sig.driver] = (slack, label, timeout)
    for drv_name, (slack, signal, timeout) in worst.items():
        k = index[drv_name]
        item = drivers_node[k] if k < len(drivers_node) and isinstance(drivers_node[k], dict) \
            else {}
        opts = item.get("options") if isinstance(item.get("options"), dict) else {}
        request_s = getattr(rig.drivers[k].options, "timeout_s", 0.0)
        ctx.add(line_of(opts, "timeout_s") or line_of(item, "options") or line_of(item),
                f"drivers[{k}].options.timeout_s",
                f"less than {request_s + slack:.3g} s: one lost reply is re-sent after this "
                f"wait, and the retried value of {signal} (its sample period, the retry's "
                f"round trip and the poll period added) must arrive within that signal's "
                f"timeout ({timeout:g} s), or every lost reply faults the rig; lower "
                "timeout_s or raise the signal's timeout_s", f"{request_s:g} s")

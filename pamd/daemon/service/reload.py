"""Config reload (SIGHUP): validate the new file, sort its changes, and build the
`reload` command the loop applies at a tick boundary.

A new config that does not validate is refused and the daemon keeps running on
the one it has, saying why. The changes of a valid one fall in three classes:

* at once: control gains (`control.pid.*`, `control.rate_feedforward_s`, and a muscle's
  own `muscles[].control.pid.*` and `rate_feedforward_s`), the plants they are judged
  against (`control.plant`, `control.position.plant`, a muscle's own: nothing in the
  tick reads them) and
  timeouts (`safety.signal_timeout_s`, the signals' `timeout_s`,
  `safety.tracking_*`, `safety.hard_limit_hold_s`, `safety.startup_timeout_s`,
  `loop.stall_timeout_s`, `loop.stall_fault_s`);
* only at rest (deferred until the rig is IDLE with nothing moving): limits and muscle data
  (`muscles[].limits.*`, `muscles[].load_kg`, `muscles[].nominal_length_mm`,
  the other `safety.*` keys, `control.slew_limit_bar_per_s`);
* only by a restart: drivers, which muscles there are and how their signals are
  wired, the loop's rate, clock and real-time settings, recording, `rig_id`,
  `calibration_file`, `state_dir`, a muscle's `type` and `custom` section, and any key
  not named above. A custom muscle's map counts by its content, not its file name
  (`muscles[i].custom.map_sha256`): a table edited on disk under an unchanged config
  is a changed map, as a changed `type` is. Changing them
  means reopening the devices: once the rig is at rest, `pamd run` restarts in place
  (`pamd.daemon.service.restart`) through the start-up that reads before it writes;
  where it cannot (a virtual-clock run, a daemon used as a library) the whole
  reload is refused.

Everything here runs in the daemon's main thread; the loop only receives the
finished `ReloadArgs` (small frozen dataclasses of numbers).
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from typing import Literal

from pamd.config.loader import LoadedConfig, effective_timeout_s
from pamd.loop.commands import MuscleSettings, ReloadArgs

Effect = Literal["now", "idle", "restart"]

_RULE_TEXT: tuple[tuple[str, Effect], ...] = (
    (r"^control\.pid\.", "now"),
    (r"^control\.rate_feedforward_s$", "now"),
    (r"^muscles\[\d+\]\.control\.(pid\.|rate_feedforward_s$)", "now"),
    # a plant is what the gains are judged against as the config loads: no tick reads it
    (r"^(muscles\[\d+\]\.)?control\.(position\.)?plant(\.|$)", "now"),
    (r"^control\.slew_limit_bar_per_s$", "idle"),
    (r"^safety\.(signal_timeout_s|latency_margin_s|tracking_band_bar|tracking_time_s"
     r"|hard_limit_hold_s|startup_timeout_s)$", "now"),
    (r"^safety\.", "idle"),
    (r"^loop\.stall_timeout_s$", "now"),
    (r"^loop\.stall_fault_s$", "now"),
    (r"^muscles\[\d+\]\.signals\.\w+\.(timeout_s|sample_period_s)$", "now"),
    (r"^muscles\[\d+\]\.(load_kg|nominal_length_mm)$", "idle"),
    (r"^muscles\[\d+\]\.limits\.", "idle"),
)
_RULES: tuple[tuple[re.Pattern[str], Effect], ...] = tuple(
    (re.compile(p), k) for p, k in _RULE_TEXT)


def classify(path: str) -> Effect:
    """When a change at key `path` may apply (see the module's docstring)."""
    for pattern, effect in _RULES:
        if pattern.search(path):
            return effect
    return "restart"


def flatten(value: object, prefix: str = "") -> dict[str, object]:
    """Key path -> leaf value of a config (dataclasses, mappings, lists); a list's
    length is kept under `path[]` so added or removed items show."""
    out: dict[str, object] = {}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            out.update(flatten(getattr(value, f.name), f"{prefix}.{f.name}" if prefix
                               else f.name))
    elif isinstance(value, dict):
        for k, v in value.items():
            out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(value, (list, tuple)):
        out[f"{prefix}[]"] = len(value)
        for i, v in enumerate(value):
            out.update(flatten(v, f"{prefix}[{i}]"))
    else:
        out[prefix] = value
    return out


def resolved(cfg: LoadedConfig) -> dict[str, object]:
    """Key path -> value of a config: its keys, and what it resolves to beyond its
    text, which may change on disk while the text does not: a custom muscle's map, by
    the digest of its rows (`muscles[i].custom.map_sha256`; a restart, as a changed
    `type` is)."""
    out = flatten(cfg.rig)
    for i, m in enumerate(cfg.rig.muscles):
        t = cfg.types.get(m.name)
        if t is not None and t.map_sha256 is not None:
            out[f"muscles[{i}].custom.map_sha256"] = t.map_sha256
    return out


def changed_paths(old: LoadedConfig, new: LoadedConfig) -> list[str]:
    """Every key path whose value differs between the two configs (`resolved`)."""
    a, b = resolved(old), resolved(new)
    return sorted(k for k in a.keys() | b.keys() if a.get(k, _MISSING) != b.get(k, _MISSING))


_MISSING = object()


@dataclass
class ReloadPlan:
    """A validated new config, what changed, and the command that applies it."""

    cfg: LoadedConfig
    now: list[str]
    idle: list[str]
    restart: list[str]
    args: ReloadArgs

    @property
    def empty(self) -> bool:
        return not (self.now or self.idle or self.restart)


def plan_reload(started: LoadedConfig, gains_cfg: LoadedConfig, limits_cfg: LoadedConfig,
                new: LoadedConfig) -> ReloadPlan:
    """Sort the changes of `new`: restart-only ones against the config the daemon
    started with, at-once ones against `gains_cfg` (whose gains are in force) and
    IDLE-only ones against `limits_cfg` (whose limits are in force)."""
    restart = [p for p in changed_paths(started, new) if classify(p) == "restart"]
    now = [p for p in changed_paths(gains_cfg, new) if classify(p) == "now"]
    idle = [p for p in changed_paths(limits_cfg, new) if classify(p) == "idle"]
    settings = tuple(_muscle_settings(new, limits_cfg, i) for i in range(len(new.rig.muscles)))
    args = ReloadArgs(config_sha256=new.sha256, at_once=tuple(now), idle_only=tuple(idle),
                      startup_timeout_s=new.rig.safety.startup_timeout_s, plan=settings)
    return ReloadPlan(new, now, idle, restart, args)


def _muscle_settings(new: LoadedConfig, limits_cfg: LoadedConfig, i: int) -> MuscleSettings:
    m = new.rig.muscles[i]
    safety = new.rig.safety
    old_load = (limits_cfg.rig.muscles[i].load_kg if i < len(limits_cfg.rig.muscles)
                else None)
    return MuscleSettings(
        muscle=m.name, pid=new.control_of(m.name).pid,
        rate_feedforward_s=new.control_of(m.name).rate_feedforward_s,
        pressure_timeout_s=effective_timeout_s(m.signals.pressure, safety),
        force_timeout_s=effective_timeout_s(m.signals.force, safety),
        length_timeout_s=effective_timeout_s(m.signals.length, safety),
        safety=new.rig.safety, limits=new.limits[m.name],
        slew_limit_bar_per_s=new.rig.control.slew_limit_bar_per_s,
        nominal_length_mm=m.nominal_length_mm,
        load_kg=None if old_load == m.load_kg else m.load_kg,
    )


def describe(paths: list[str], old: LoadedConfig, new: LoadedConfig) -> str:
    """`key old -> new, ...` for the log (a map's digest: its first 12 digits, and the
    file it was read from)."""
    a, b = resolved(old), resolved(new)

    def said(cfg: LoadedConfig, values: dict[str, object], p: str) -> str:
        v = values.get(p, "(none)")
        if not p.endswith(".map_sha256") or not isinstance(v, str):
            return repr(v)
        i = int(p.split("[", 1)[1].split("]", 1)[0])
        return f"{v[:12]} ({cfg.types[cfg.rig.muscles[i].name].map_file})"

    return ", ".join(f"{p} {said(old, a, p)} -> {said(new, b, p)}" for p in paths)

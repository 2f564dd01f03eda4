"""Load and validate a rig config in one place: syntax, schema, then the checks that
span several keys (names, drivers and channels, limits against ratings, valve full
scale). Nothing starts unless this returns."""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import os
from dataclasses import dataclass
from importlib import resources
from typing import Protocol, runtime_checkable

from pamd.config.actuation_rules import check_actuation, check_sim_sample_periods, check_sim_stalls
from pamd.config.chain_rules import check_safety_chain
from pamd.config.clock import check_loop_clock
from pamd.config.control_schema import ControlConfig
from pamd.config.drivertype import BindsMuscleTypes, driver_type
from pamd.config.gains import check_gains
from pamd.config.muscle_types import Ratings, ratings_of, resolve
from pamd.config.names import NAME_RE, check_chunk
from pamd.config.plausibility_rules import check_plausibility_thresholds
from pamd.config.request_timeouts import check_request_timeouts
from pamd.config.safety_schema import SafetyConfig
from pamd.config.schema import InputSignal, MuscleConfig, RigConfig, SignalConfig, muscle_control
from pamd.config.timing_rules import check_timing
from pamd.muscle_type import MuscleType
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import DriverError
from pamd.wire.schema.engine import Context, build_dataclass, describe, line_of
from pamd.wire.schema.yamlload import load_yaml_text, read_text

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MuscleLimitsResolved:
    """A muscle's soft and hard limits with ratings filled in."""

    max_pressure_bar: float
    max_contraction: float
    max_pretension: float
    hard_max_pressure_bar: float
    hard_max_contraction: float
    hard_max_pretension: float


@dataclass(frozen=True)
class LoadedConfig:
    """A validated config with what was derived from it."""

    rig: RigConfig
    path: str
    text: str
    limits: dict[str, MuscleLimitsResolved]
    #: the config's own `calibration_file`, resolved; None: in the run's state directory
    #: (pamd.daemon.service.state.calibration_path), or for the run only without one
    calibration_path: str | None
    #: values above their safe ceiling that `safety.relax_ceilings` let pass (said at start)
    warnings: tuple[str, ...] = ()
    #: each muscle's type by muscle name: its ratings, geometry and force map
    types: dict[str, MuscleType] = dataclasses.field(default_factory=dict)

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()

    @property
    def period_s(self) -> float:
        return 1.0 / self.rig.loop.rate_hz

    def muscle(self, name: str) -> MuscleConfig:
        for m in self.rig.muscles:
            if m.name == name:
                return m
        raise KeyError(name)

    def muscle_type(self, name: str) -> MuscleType:
        """Muscle `name`'s type (`muscles[].type`), resolved: its ratings, geometry and
        force map (a custom type's read from its table and checked)."""
        return self.types[name]

    def control_of(self, name: str) -> ControlConfig:
        """Muscle `name`'s control section: the rig's, with each gain its own
        `muscles[].control` names in place of the rig-wide one."""
        return muscle_control(self.rig.control, self.muscle(name).control)


def builtin_config_path(name: str = "sim.yaml") -> str:
    """Path of a config shipped inside the package (the simulated rig by default)."""
    return str(resources.files("pamd.data").joinpath(name))


def load_config(path: str | None = None, overrides: JsonObject | None = None) -> LoadedConfig:
    """Read, parse and validate a rig config file (default: the built-in sim rig).

    `overrides` replaces top-level sections' keys after parsing (e.g. the CLI's
    `--clock virtual` is `{"loop": {"clock": "virtual"}}`)."""
    path = path or builtin_config_path()
    return load_config_text(read_text(path, "a readable config file"), path, overrides)


def load_config_text(text: str, path: str, overrides: JsonObject | None = None) -> LoadedConfig:
    raw = load_yaml_text(text, path)
    ctx = Context(path)
    if not isinstance(raw, dict):
        found = "an empty file" if raw is None else describe(raw)
        ctx.add(line_of(raw) or 1, "", "a mapping with drivers and muscles", found)
        ctx.raise_if_any()
    if overrides:
        _override(raw, overrides, ctx)
    rig = build_dataclass(RigConfig, raw, ctx, "", 1)
    ctx.raise_if_any()
    assert rig is not None  # a problem building it is in ctx (raised above)
    warnings = _check_safety_bounds(rig, raw, ctx)
    drivers_node = raw.get("drivers", [])
    limits, types = _check_muscles(rig, raw.get("muscles", []), path, ctx)
    rig, channels, digital, lost_reply = _check_drivers(rig, drivers_node, types, path, ctx)
    _check_signals(rig, raw.get("muscles", []), channels, ctx)
    check_actuation(rig, raw.get("muscles", []), digital, ctx)
    check_sim_sample_periods(rig, drivers_node, ctx, effective_timeout_s)
    check_request_timeouts(rig, drivers_node, lost_reply, ctx, effective_timeout_s,
                           input_signals(rig, raw))
    check_plausibility_thresholds(rig, raw, limits, types, ctx)
    check_sim_stalls(rig, drivers_node, ctx)
    check_safety_chain(rig, raw.get("safety_chain"), ctx)
    check_loop_clock(rig, raw, ctx)
    check_timing(rig, raw, ctx)
    ctx.raise_if_any()
    warnings += check_gains(rig, raw, ctx)  # the loops on their plants, once all is valid
    ctx.raise_if_any()
    cal_path = None if not rig.calibration_file else os.path.join(
        os.path.dirname(os.path.abspath(path)), os.path.expanduser(rig.calibration_file))
    for warning in warnings:
        log.warning("%s", warning)
    return LoadedConfig(rig, path, text, limits, cal_path, warnings, types)


def effective_timeout_s(sig: SignalConfig, safety: SafetyConfig) -> float:
    """The age at which an input signal (a muscle's, the safety chain's) is stale. The
    physics: a healthy device delivers a fresh sample at least once per update period
    (`sample_period_s`; none stated: every poll is a new sample, 0), late by at most the
    delivery latency the rig declares (`safety.latency_margin_s`: a lost reply's retry,
    a driver thread held up, a frame waiting in a socket, a busy host); a value older
    than their sum comes from a device that stopped. Never less than the signal's
    `timeout_s` (or the safety default). The margin applies whether or not a period is
    stated: an e-stop input with none got 50 ms where its rig's muscle inputs got
    101 ms, and a loaded PC opened the chain falsely."""
    timeout = sig.timeout_s or safety.signal_timeout_s
    return max(timeout, (sig.sample_period_s or 0.0) + safety.latency_margin_s)


def input_signals(rig: RigConfig, raw: JsonValue) -> list[InputSignal]:
    """Every input signal of the rig, with its config path, its name and its raw node:
    each muscle's pressure, force and length, and the safety chain's estop, supply and
    reset (whose staleness derives the same way: `effective_timeout_s`)."""
    root = raw if isinstance(raw, dict) else {}
    muscles_node = root.get("muscles")
    muscles_node = muscles_node if isinstance(muscles_node, list) else []
    found: list[InputSignal] = []
    for i, m in enumerate(rig.muscles):
        mnode = muscles_node[i] if i < len(muscles_node) else {}
        snode = (mnode.get("signals") if isinstance(mnode, dict) else None) or {}
        for name in ("pressure", "force", "length"):
            node = snode.get(name) if isinstance(snode, dict) else None
            found.append(InputSignal(f"muscles[{i}].signals.{name}", f"{m.name}.{name}",
                                     getattr(m.signals, name), node or {}))
    cnode = root.get("safety_chain")
    cnode = cnode if isinstance(cnode, dict) else {}
    for name in ("estop", "supply", "reset"):
        sig = getattr(rig.safety_chain, name)
        if sig is not None:
            found.append(InputSignal(f"safety_chain.{name}", f"safety_chain.{name}", sig,
                                     cnode.get(name) or {}))
    return found


def _override(raw: dict[str, JsonValue], overrides: JsonObject, ctx: Context) -> None:
    """A section's keys replaced (`{"loop": {"clock": "virtual"}}`); a list of named
    items (`muscles`) by name (`{"muscles": {"m1": {"load_kg": 45.0}}}`: `pamd run
    --load-kg m1=45`), an unknown name refused."""
    for section, values in overrides.items():
        node = raw.setdefault(section, {})
        if isinstance(node, dict):
            node.update(values)
        elif isinstance(node, list) and isinstance(values, dict):
            items = {item.get("name"): item for item in node if isinstance(item, dict)}
            for name, changes in values.items():
                if name in items:
                    items[name].update(changes)
                else:
                    known = ", ".join(str(n) for n in items)
                    ctx.add(line_of(node), f"{section}[name={name}]",
                            f"one of the config's {section} ({known})", repr(name))


def _check_safety_bounds(rig: RigConfig, raw: JsonValue, ctx: Context) -> tuple[str, ...]:
    """Checks that keep safety on: a key-safe rig id, a loop the stall check can watch,
    sample periods within their timeouts, and the safe ceilings (refused, or with
    `safety.relax_ceilings` let through as warnings)."""
    problem = check_chunk("rig_id", rig.rig_id) if rig.rig_id else "rig_id is empty"
    if problem or len(rig.rig_id) > 64:
        ctx.add(line_of(raw, "rig_id"), "rig_id", "a name of letters, digits, '_', '-' and "
                "'.' (not first), at most 64 characters, usable in Zenoh keys and file "
                "names", f"{rig.rig_id!r}" + (f" ({problem})" if problem else ""))
    loop_node = raw.get("loop") or {}
    period_s = 1.0 / rig.loop.rate_hz
    if 2.0 * period_s > rig.loop.stall_timeout_s:
        ctx.add(line_of(loop_node, "rate_hz"), "loop.rate_hz",
                f"at least {2.0 / rig.loop.stall_timeout_s:g} Hz (two periods within "
                f"loop.stall_timeout_s = {rig.loop.stall_timeout_s:g} s, or the stall check "
                "cannot see a stalled loop)", f"{rig.loop.rate_hz:g} Hz")
    for path, _, sig, node in input_signals(rig, raw):
        timeout = sig.timeout_s or rig.safety.signal_timeout_s
        if sig.sample_period_s is not None and sig.sample_period_s > timeout:
            ctx.add(line_of(node, "sample_period_s"), f"{path}.sample_period_s",
                    f"at most the signal's timeout ({timeout:g} s): a value cannot be "
                    "fresher than its device samples it; raise timeout_s",
                    f"{sig.sample_period_s:g} s")
    if not rig.safety.relax_ceilings:
        ctx.issues.extend(ctx.over_ceiling)
        return ()
    return tuple(f"{i.file}:{i.line}: {i.path}: {i.found} is above its safe ceiling; "
                 "allowed by safety.relax_ceilings: true" for i in ctx.over_ceiling)


def _check_name(ctx: Context, name: str, seen: set[str], line: int | None, path: str) -> None:
    if not NAME_RE.match(name):
        ctx.add(line, path, "a name of letters, digits, '_' or '-' starting with a letter",
                repr(name))
    if name in seen:
        ctx.add(line, path, "a unique name", f"{name!r} a second time")
    seen.add(name)


@runtime_checkable
class _RetriesLostReplies(Protocol):
    """A driver that re-sends an unanswered request (pamd.drivers.modbus): how much
    later a fresh input can arrive when one reply is lost."""

    def lost_reply_s(self) -> float: ...


def _check_drivers(rig: RigConfig, node: JsonValue, types: dict[str, MuscleType], path: str,
                   ctx: Context
                   ) -> tuple[RigConfig, dict[str, dict[str, str]], dict[str, set[str]],
                              dict[str, float]]:
    """Validate each driver's type and options; returns the config with typed options
    (a simulated rig's muscles of the types of the rig muscles they stand for: `types`)
    and, per driver whose options are valid, {channel name: 'in' | 'out'}, the
    names of its digital outputs and, for a driver that retries lost replies, its
    `lost_reply_s()`."""
    seen: set[str] = set()
    built = []
    channel_map: dict[str, dict[str, str]] = {}
    digital: dict[str, set[str]] = {}
    lost_reply: dict[str, float] = {}
    for i, drv in enumerate(rig.drivers):
        item = node[i]
        _check_name(ctx, drv.name, seen, line_of(item, "name"), f"drivers[{i}].name")
        try:
            cls = driver_type(drv.type)
        except DriverError as exc:
            ctx.add(line_of(item, "type"), f"drivers[{i}].type", "an installed driver type",
                    f"{drv.type!r} ({exc})")
            built.append(drv)
            continue
        n_before = len(ctx.issues)
        options = build_dataclass(cls.options_type, item.get("options"), ctx,
                                  f"drivers[{i}].options", line_of(item, "options"))
        if len(ctx.issues) == n_before and isinstance(cls, BindsMuscleTypes):
            options = cls.bind_muscle_types(options, _bound_types(rig, drv.name, types),
                                            os.path.dirname(os.path.abspath(path)))
        if len(ctx.issues) == n_before:
            try:  # the driver's own cross-field checks (it must not do I/O here)
                built_driver = cls(drv.name, options)
                channels = built_driver.channels()
            except (DriverError, ValueError) as exc:
                ctx.add(line_of(item, "options"), f"drivers[{i}].options",
                        f"options that driver type {drv.type!r} accepts", str(exc))
            else:
                channel_map[drv.name] = {c.name: c.direction for c in channels}
                digital[drv.name] = {c.name for c in channels
                                     if c.direction == "out" and c.digital}
                if isinstance(built_driver, _RetriesLostReplies):
                    lost_reply[drv.name] = built_driver.lost_reply_s()
        built.append(dataclasses.replace(drv, options=options))
    return dataclasses.replace(rig, drivers=tuple(built)), channel_map, digital, lost_reply


def _bound_types(rig: RigConfig, driver: str, types: dict[str, MuscleType]
                 ) -> dict[str, MuscleType]:
    """The channels of `driver` the rig's muscles read, each with its muscle's type."""
    out = {}
    for m in rig.muscles:
        if m.name in types:
            for sig in (m.signals.pressure, m.signals.force, m.signals.length):
                if sig.driver == driver:
                    out[sig.channel] = types[m.name]
    return out


def _check_muscles(rig: RigConfig, node: JsonValue, path: str, ctx: Context
                   ) -> tuple[dict[str, MuscleLimitsResolved], dict[str, MuscleType]]:
    """Each muscle's name, resolved limits and type (the muscles whose type resolves)
    and its regulator's clamp."""
    seen: set[str] = set()
    limits: dict[str, MuscleLimitsResolved] = {}
    types: dict[str, MuscleType] = {}
    if not rig.muscles:
        ctx.add(line_of(node), "muscles", "at least one muscle", "none")
    for i, m in enumerate(rig.muscles):
        item = node[i]
        base = f"muscles[{i}]"
        _check_name(ctx, m.name, seen, line_of(item, "name"), f"{base}.name")
        rating = ratings_of(m, item, base, ctx)
        if rating is not None:
            lim = limits[m.name] = _limits_of(m, rating, item, base, rig.safety, ctx)
            mtype = resolve(m, rating, lim, item, base, path, ctx)
            if mtype is not None:
                types[m.name] = mtype
        if m.signals.valve is not None and rating is not None:
            # required or refused: pamd.config.actuation_rules
            _check_valve(m, limits[m.name].max_pressure_bar, rating.max_pressure_bar,
                         (item.get("signals") or {}).get("valve") or {}, base, ctx)
    return limits, types


def _check_signals(rig: RigConfig, node: JsonValue, channels: dict[str, dict[str, str]],
                   ctx: Context) -> None:
    """Each muscle's signals name a driver of the rig and a channel of it."""
    known_drivers = {d.name for d in rig.drivers}
    for i, m in enumerate(rig.muscles):
        _check_muscle_signals(m, node[i].get("signals") or {}, f"muscles[{i}]",
                              known_drivers, channels, ctx)


def _limits_of(m: MuscleConfig, rating: Ratings, item: JsonValue, base: str,
               s: SafetyConfig, ctx: Context) -> MuscleLimitsResolved:
    """The muscle's limits: its own where it sets them (never above its type's ratings),
    else the ratings; the hard limits the safety margins beyond."""
    if m.load_kg > rating.max_load_kg:
        ctx.add(line_of(item, "load_kg"), f"{base}.load_kg",
                f"at most {rating.max_load_kg} kg ({m.type} rating)", f"{m.load_kg} kg")
    lim_node = item.get("limits") or {}
    resolved = {}
    for key, rated in (("max_pressure_bar", rating.max_pressure_bar),
                       ("max_contraction", rating.max_contraction),
                       ("max_pretension", rating.max_pretension)):
        value = getattr(m.limits, key)
        if value is not None and value > rated:
            ctx.add(line_of(lim_node, key), f"{base}.limits.{key}",
                    f"at most {rated} (the {m.type} rating)", str(value))
        resolved[key] = rated if value is None else min(value, rated)
    return MuscleLimitsResolved(
        hard_max_pressure_bar=resolved["max_pressure_bar"] + s.pressure_margin_bar,
        hard_max_contraction=resolved["max_contraction"] + s.contraction_margin,
        hard_max_pretension=resolved["max_pretension"] + s.contraction_margin,
        **resolved,
    )


def _check_muscle_signals(m: MuscleConfig, sig_node: JsonValue, base: str,
                          known_drivers: set[str], channels: dict[str, dict[str, str]],
                          ctx: Context) -> None:
    """Each signal names a driver of the rig and a channel of it in the right direction."""
    for sig_name in ("pressure", "force", "length", "valve", "inflate", "exhaust"):
        sig = getattr(m.signals, sig_name)
        if sig is None:
            continue
        snode = sig_node.get(sig_name) or {}
        spath = f"{base}.signals.{sig_name}"
        direction = "out" if sig_name in ("valve", "inflate", "exhaust") else "in"
        if sig.driver not in known_drivers:
            ctx.add(line_of(snode, "driver"), f"{spath}.driver",
                    f"one of the drivers {', '.join(sorted(known_drivers))}",
                    repr(sig.driver))
        elif sig.driver in channels:
            chans = channels[sig.driver]
            if chans.get(sig.channel) != direction:
                names = [c for c, d in chans.items() if d == direction]
                ctx.add(line_of(snode, "channel"), f"{spath}.channel",
                        f"an {'output' if direction == 'out' else 'input'} channel of "
                        f"driver {sig.driver!r} ({', '.join(names)})", repr(sig.channel))
        if sig.gain == 0.0:
            ctx.add(line_of(snode, "gain"), f"{spath}.gain", "a non-zero gain", "0")


def _check_valve(m: MuscleConfig, limit_bar: float, rated_bar: float, vnode: JsonValue, base: str,
                 ctx: Context) -> None:
    """A regulator's full scale must be clamped in config to the muscle's rating."""
    v = m.signals.valve
    assert v is not None
    path = f"{base}.signals.valve"
    if v.raw_max is None:
        ctx.add(line_of(vnode), f"{path}.raw_max",
                "raw_max: the highest raw value written to the regulator (its clamp)", "none")
        return
    raw_min = 0.0 if v.raw_min is None else v.raw_min
    if v.raw_max <= raw_min:
        ctx.add(line_of(vnode, "raw_max"), f"{path}.raw_max", f"more than raw_min ({raw_min})",
                str(v.raw_max))
        return
    full_scale = max(v.gain * v.raw_max + v.offset, v.gain * raw_min + v.offset)
    if full_scale > rated_bar + 1e-9:
        clamp = (rated_bar - v.offset) / v.gain
        ctx.add(line_of(vnode, "raw_max"), f"{path}.raw_max",
                f"a full scale of at most {rated_bar} bar (the {m.type} rating): set raw_max "
                f"to {clamp:g} or lower", f"{full_scale:g} bar at raw_max {v.raw_max:g}")

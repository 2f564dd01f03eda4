"""Load and validate a rig config in one place: syntax, schema, then the checks that
span several keys (names, drivers and channels, limits against ratings, valve full
scale). Nothing starts unless this returns."""

from __future__ import annotations

import dataclasses
import hashlib
import os
import re
from dataclasses import dataclass
from importlib import resources
from typing import Any

from pamd.config.engine import Context, build_dataclass, line_of
from pamd.config.schema import MuscleConfig, RigConfig
from pamd.config.yamlload import load_yaml_text, read_text
from pamd.errors import DriverError
from pamd.muscle import MUSCLE_TYPES

NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")


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
    calibration_path: str
    #: muscle name -> `pamd.control.feedforward.LoadedModel` (its `model_file`)
    models: dict[str, Any] = dataclasses.field(default_factory=dict)

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


def builtin_config_path(name: str = "sim.yaml") -> str:
    """Path of a config shipped inside the package (the simulated rig by default)."""
    return str(resources.files("pamd.data").joinpath(name))


def load_config(path: str | None = None, overrides: dict[str, Any] | None = None) -> LoadedConfig:
    """Read, parse and validate a rig config file (default: the built-in sim rig).

    `overrides` replaces top-level sections' keys after parsing (e.g. the CLI's
    `--clock virtual` is `{"loop": {"clock": "virtual"}}`)."""
    path = path or builtin_config_path()
    return load_config_text(read_text(path, "a readable config file"), path, overrides)


def load_config_text(text: str, path: str, overrides: dict[str, Any] | None = None) -> LoadedConfig:
    raw = load_yaml_text(text, path)
    ctx = Context(path)
    if raw is None:
        ctx.add(1, "", "a mapping with drivers and muscles", "an empty file")
        ctx.raise_if_any()
    if overrides:
        for section, values in overrides.items():
            node = raw.setdefault(section, {})
            if isinstance(node, dict):
                node.update(values)
    rig = build_dataclass(RigConfig, raw, ctx, "", 1)
    ctx.raise_if_any()
    drivers_node = raw.get("drivers", [])
    rig, channels = _check_drivers(rig, drivers_node, ctx)
    limits = _check_muscles(rig, raw.get("muscles", []), channels, ctx)
    ctx.raise_if_any()
    models = _load_models(rig, raw.get("muscles", []), path, limits, ctx)
    ctx.raise_if_any()
    cal = rig.calibration_file or os.path.splitext(os.path.basename(path))[0] + ".cal.yaml"
    cal_path = os.path.join(os.path.dirname(os.path.abspath(path)), cal)
    return LoadedConfig(rig, path, text, limits, cal_path, models)


def _load_models(rig: RigConfig, node: Any, path: str, limits: dict[str, MuscleLimitsResolved],
                 ctx: Context) -> dict[str, Any]:
    """Each muscle's `model_file`, read and checked against the muscle (file I/O, here,
    before anything starts; the controller compiles it)."""
    from pamd.control.feedforward import LoadedModel
    from pamd.errors import ModelError

    models: dict[str, Any] = {}
    base = os.path.dirname(os.path.abspath(path))
    for i, m in enumerate(rig.muscles):
        if m.model_file is None:
            continue
        file = os.path.join(base, os.path.expanduser(m.model_file))
        try:
            models[m.name] = LoadedModel.read(file, m, limits[m.name])
        except ModelError as exc:
            ctx.add(line_of(node[i], "model_file"), f"muscles[{i}].model_file",
                    "a model file that loads and fits this muscle", str(exc))
    return models


def _check_name(ctx: Context, name: str, seen: set[str], line: int | None, path: str) -> None:
    if not NAME_RE.match(name):
        ctx.add(line, path, "a name of letters, digits, '_' or '-' starting with a letter",
                repr(name))
    if name in seen:
        ctx.add(line, path, "a unique name", f"{name!r} a second time")
    seen.add(name)


def _check_drivers(rig: RigConfig, node: Any,
                   ctx: Context) -> tuple[RigConfig, dict[str, dict[str, str]]]:
    """Validate each driver's type and options; returns the config with typed options
    and, per driver whose options are valid, {channel name: 'in' | 'out'}."""
    from pamd.drivers import load_driver_class

    seen: set[str] = set()
    built = []
    channel_map: dict[str, dict[str, str]] = {}
    for i, drv in enumerate(rig.drivers):
        item = node[i]
        _check_name(ctx, drv.name, seen, line_of(item, "name"), f"drivers[{i}].name")
        try:
            cls = load_driver_class(drv.type)
        except DriverError as exc:
            ctx.add(line_of(item, "type"), f"drivers[{i}].type", "an installed driver type",
                    f"{drv.type!r} ({exc})")
            built.append(drv)
            continue
        n_before = len(ctx.issues)
        options = build_dataclass(cls.options_type, item.get("options"), ctx,
                                  f"drivers[{i}].options", line_of(item, "options"))
        if len(ctx.issues) == n_before:
            try:  # the driver's own cross-field checks (it must not do I/O here)
                channels = cls(drv.name, options).channels()
            except (DriverError, ValueError) as exc:
                ctx.add(line_of(item, "options"), f"drivers[{i}].options",
                        f"options that driver type {drv.type!r} accepts", str(exc))
            else:
                channel_map[drv.name] = {c.name: c.direction for c in channels}
        built.append(dataclasses.replace(drv, options=options))
    return dataclasses.replace(rig, drivers=tuple(built)), channel_map


def _check_muscles(rig: RigConfig, node: Any, channels: dict[str, dict[str, str]],
                   ctx: Context) -> dict[str, MuscleLimitsResolved]:
    known_drivers = {d.name for d in rig.drivers}
    seen: set[str] = set()
    limits: dict[str, MuscleLimitsResolved] = {}
    if not rig.muscles:
        ctx.add(line_of(node), "muscles", "at least one muscle", "none")
    for i, m in enumerate(rig.muscles):
        item = node[i]
        base = f"muscles[{i}]"
        _check_name(ctx, m.name, seen, line_of(item, "name"), f"{base}.name")
        rating = MUSCLE_TYPES[m.type]
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
        s = rig.safety
        limits[m.name] = MuscleLimitsResolved(
            hard_max_pressure_bar=resolved["max_pressure_bar"] + s.pressure_margin_bar,
            hard_max_contraction=resolved["max_contraction"] + s.contraction_margin,
            hard_max_pretension=resolved["max_pretension"] + s.contraction_margin,
            **resolved,
        )
        sig_node = item.get("signals") or {}
        for sig_name in ("pressure", "force", "length", "valve", "exhaust"):
            sig = getattr(m.signals, sig_name)
            if sig is None:
                continue
            snode = sig_node.get(sig_name) or {}
            spath = f"{base}.signals.{sig_name}"
            direction = "out" if sig_name in ("valve", "exhaust") else "in"
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
        _check_valve(m, resolved["max_pressure_bar"], rating.max_pressure_bar,
                     sig_node.get("valve") or {}, base, ctx)
    return limits


def _check_valve(m: MuscleConfig, limit_bar: float, rated_bar: float, vnode: Any, base: str,
                 ctx: Context) -> None:
    """A regulator's full scale must be clamped in config to the muscle's rating."""
    v = m.signals.valve
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

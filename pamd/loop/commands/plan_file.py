"""A remote `collect`'s plan: file `name` in `telemetry.plans_dir`, within the limits
(`pamd.loop.commands.named_files`), parsed and checked against the rig in a child process
(`pamd.loop.commands.offload`: a YAML parse of a 1 MiB plan is seconds of the interpreter
lock the loop needs); the refusal names file, line and key and never quotes the
file."""

from __future__ import annotations

from pamd.config.loader import LoadedConfig
from pamd.loop.commands import named_files
from pamd.loop.commands.offload import run_isolated
from pamd.loop.experiment.plan import Plan, parse_plan
from pamd.wire.errors import CommandRefused, PamdError


def parse_named_plan(path: str, name: str, cfg: LoadedConfig) -> Plan:
    """In the child: the plan file read within the limits, parsed and checked."""
    try:
        nf = named_files.read_limited(path, name, "plan", named_files.PLAN_MAX_BYTES)
    except CommandRefused as exc:
        raise CommandRefused(f"collect: plan refused: {exc}") from None
    try:
        return parse_plan(nf.text, path, cfg)
    except PamdError as exc:
        raise CommandRefused(f"collect: plan refused: "
                             f"{named_files.issues_text(exc, name)}") from None
    except RecursionError:
        raise CommandRefused(f"collect: plan refused: {name!r} is nested too deep") from None
    except (OverflowError, ValueError, ArithmeticError) as exc:
        raise CommandRefused(f"collect: plan refused: {name!r}: a number out of its "
                             f"domain ({exc.__class__.__name__})") from None


def read_plan(name: str, cfg: LoadedConfig, isolated: bool = True) -> tuple[Plan, str]:
    """The plan named `name` and its path; CommandRefused says why not. `isolated`
    (the daemon's way) reads it in a child process; False reads it here."""
    try:
        path = named_files.resolve(name, named_files.configured_dir(cfg, "plans_dir"),
                                   "plan", "plans_dir")
    except CommandRefused as exc:
        raise CommandRefused(f"collect: plan refused: {exc}") from None
    if not isolated:
        return parse_named_plan(path, name, cfg), path
    plan = run_isolated(parse_named_plan, path, name, cfg,
                        time_limit_s=named_files.parse_time_limit_s(cfg),
                        what=f"collect: plan refused: {name!r}")
    return plan, path

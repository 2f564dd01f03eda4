"""Each command verb's spec is declared once (`pamd.wire.verbs.table.VERBS`) and its handler once
(`pamd.loop.commands.verb_registry.Verb`); the parser, the loop's dispatcher, the io process's
routing, the status and `pamd cmd --help` derive from them."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from pamd.client.cli.main import build_parser
from pamd.client.cli.net import verb_parser
from pamd.loop.commands import (
    REGISTRY,
    Command,
    Verb,
    VerbRegistry,
    apply_command,
    parse_command,
)
from pamd.loop.commands import (
    adapt_verbs as adapt,
)
from pamd.loop.commands import (
    motion_verbs as motion,
)
from pamd.loop.commands import (
    plan_verbs as plan,
)
from pamd.loop.commands import (
    rig_verbs as rig,
)
from pamd.wire.errors import CommandRefused
from pamd.wire.verbs.args import NoArgs
from pamd.wire.verbs.table import VERBS, VerbSpec, VerbTable

PUBLIC = ("setpoint", "profile", "mode", "model", "adapt", "hold", "resume", "stop", "estop",
          "reset", "home", "tare", "load", "confirm", "pause", "collect")


def test_the_registry_holds_every_declared_verb_once() -> None:
    declared = motion.VERBS + adapt.VERBS + rig.VERBS + plan.VERBS
    assert sorted(REGISTRY.names) == sorted(PUBLIC)
    assert [v.name for v in declared if not v.internal] == list(REGISTRY.names)
    assert [v.name for v in declared if v.internal] == ["reload"]
    assert REGISTRY.urgent == ("stop", "estop")
    assert REGISTRY.main_thread == ("model", "collect")
    assert REGISTRY.pressure_fields == {"setpoint": ("bar",),
                                        "profile": ("min_bar", "max_bar", "to_bar")}
    for v in declared:
        assert dataclasses.is_dataclass(v.args) and v.help and callable(v.handler)
    with pytest.raises(ValueError, match="'hold' is declared twice"):
        VerbRegistry(rig.VERBS + rig.VERBS[:1])


def test_every_public_verb_parses_and_the_internal_one_is_unknown_to_clients() -> None:
    for name in PUBLIC:
        v = REGISTRY.public(name)
        assert v is not None
        fields = [f for f in dataclasses.fields(v.args)
                  if f.default is dataclasses.MISSING and f.default_factory is
                  dataclasses.MISSING]
        payload: dict[str, Any] = {f.name: {"muscle": "m1", "mode": "pressure",
                                            "file": "m.json", "plan_file": "p.yaml",
                                            "length_mm": 200.0, "load_kg": 10.0}[f.name]
                                   for f in fields}
        cmd = parse_command(name, payload)
        assert isinstance(cmd.args, v.args)
    with pytest.raises(CommandRefused) as exc:
        parse_command("reload", {})
    assert str(exc.value) == ("unknown command 'reload'; known: " + ", ".join(REGISTRY.names))
    assert REGISTRY.get("reload") is not None and REGISTRY.public("reload") is None
    assert "reload" not in REGISTRY


def test_the_dispatcher_runs_the_declared_handler_and_refuses_an_undeclared_verb(
        harness: Any) -> None:
    h = harness()
    h.step(0.01)
    verdict = apply_command(h.ctrl, Command("no-such-verb", NoArgs()))
    assert verdict == {"ok": False, "error": "unknown command 'no-such-verb'"}
    assert h.cmd("hold")["ok"] and h.state == "HOLD"  # rig.VERBS' hold handler ran


def test_cmd_help_and_each_verbs_options_come_from_the_declarations(
        capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["cmd", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for v in REGISTRY:
        assert " ".join(f"{v.name} {v.help}".split()) in text
    assert "reload" not in text
    p = verb_parser("tare")
    assert p.description == REGISTRY.public("tare").help  # type: ignore[union-attr]
    ns = p.parse_args(["--muscle", "m1", "--load-kg", "30"])
    assert ns.field_muscle == "m1" and ns.field_load_kg == 30.0


def test_a_new_verb_is_its_spec_and_its_handler() -> None:
    """The spec (what the io process parses and routes by) and the loop's handler are
    declared apart; the registry refuses one without the other."""
    def _ping(ctrl: Any, a: NoArgs) -> dict[str, Any]:
        return {"pong": True}

    ping = VerbSpec("ping", NoArgs, "answer pong", urgent=True)
    reg = VerbRegistry(rig.VERBS + (Verb(ping, _ping),))
    assert reg.names[-1] == "ping" and reg.is_urgent("ping") and "ping" in reg
    assert reg.get("ping").handler(None, NoArgs()) == {"pong": True}  # type: ignore[union-attr]
    specs = VerbTable(tuple(v.spec for v in rig.VERBS if not v.internal) + (ping,))
    with pytest.raises(ValueError, match=r"without a handler: \['ping'\]"):
        VerbRegistry(rig.VERBS, specs)
    with pytest.raises(ValueError, match=r"without a public spec: \['ping'\]"):
        VerbRegistry(rig.VERBS + (Verb(ping, _ping),), VerbTable(specs_of(rig.VERBS)))


def specs_of(verbs: tuple[Verb, ...]) -> tuple[VerbSpec, ...]:
    return tuple(v.spec for v in verbs if not v.internal)


def test_the_io_side_specs_are_the_loops_verbs() -> None:
    """`pamd.wire.verbs.table.VERBS` (the io process's) and the loop's registry name the same
    public verbs, in the same order, with the same specs."""
    assert VERBS.names == REGISTRY.names
    assert all(REGISTRY.public(s.name).spec is s for s in VERBS)  # type: ignore[union-attr]

"""The field table (pamd.wire.declare.fields) is the one declaration of every recorded value:
the tick's offsets, the MCAP/ROS 2 schemas (read back by the independent parser of
`mcap_ros2`), the exports' units and descriptions, the Foxglove layout and the
generated docs/fields-reference.md all derive from it; each test fails on a drift."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from mcap_ros2._vendor.rosidl_adapter.parser import parse_message_string

from pamd.client import field_info as view_fields
from pamd.client.layout import PANELS, build_layout
from pamd.iohost.recorder import record_schemas
from pamd.loop import loop
from pamd.loop.control import controller, muscle
from pamd.wire import tick
from pamd.wire.declare import fields
from pamd.wire.declare import fields_doc as docs
from pamd.wire.declare.deprecated import FLAG_NAMES
from pamd.wire.record import cdr

ROOT = Path(__file__).resolve().parents[2]


def test_the_generated_reference_is_current() -> None:
    path = ROOT / "docs" / "fields-reference.md"
    assert path.read_text() == docs.generate(), (
        "docs/fields-reference.md is stale: python -m pamd.wire.declare.fields_doc > "
        "docs/fields-reference.md")


def test_the_reference_names_every_field_flag_and_event() -> None:
    from pamd.wire.declare import events
    text = docs.generate()
    for f in fields.BY_NAME.values():
        assert f"| `{f.name}` | {f.unit} | {f.type} |" in text
    for flag in fields.Flag:
        assert f"| {flag.name} |" in text
    for k in events.DECLARED:
        assert f"### `{k.name}`" in text


def test_tick_layout_and_offsets_follow_the_table() -> None:
    assert tuple(f.name for f in fields.LOOP) == tick.LOOP_FIELDS
    assert tuple(f.name for f in fields.MUSCLE) == tick.MUSCLE_FIELDS
    layout = tick.TickLayout(["a", "b"])
    assert layout.size == len(fields.LOOP) + 2 * len(fields.MUSCLE)
    assert layout.names()[len(fields.LOOP)] == f"a.{fields.MUSCLE[0].name}"
    offsets = {n: v for n, v in vars(tick).items()
               if (n.startswith("I_") or n.startswith("M_")) and isinstance(v, int)}
    # every constant is the position of a distinct field of its block (a stage may
    # also take its own: `muscle_offset(name)` at import)
    loop = [v for n, v in offsets.items() if n.startswith("I_")]
    muscle = [v for n, v in offsets.items() if n.startswith("M_")]
    assert len(set(loop)) == len(loop) and set(loop) <= set(range(len(fields.LOOP)))
    assert len(set(muscle)) == len(muscle) and set(muscle) <= set(range(len(fields.MUSCLE)))
    assert tick.M_FLAGS == tick.muscle_offset("flags") == tick.MUSCLE_FIELDS.index("flags")
    assert tick.LOOP_FIELDS.index("segment") == tick.I_SEGMENT
    with pytest.raises(KeyError, match="not a muscle field"):
        tick.muscle_offset("no_such_field")


def _stored(tree: ast.AST, prefix: str) -> set[str]:
    """Names starting with `prefix` in the index of a subscript store (rec[b + M_X] = ...)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign):
            for target in node.targets:
                if isinstance(target, ast.Subscript):
                    out |= {n.id for n in ast.walk(target.slice)
                            if isinstance(n, ast.Name) and n.id.startswith(prefix)}
    return out


def test_the_muscle_stage_writes_every_muscle_field() -> None:
    """`MuscleController._record` stores each muscle field of the table, by its offset."""
    src = (ROOT / "pamd" / "loop" / "control" / "muscle.py").read_text()
    fn = next(n for n in ast.walk(ast.parse(src))
              if isinstance(n, ast.FunctionDef) and n.name == "_record")
    offsets = {getattr(muscle, n) for n in _stored(fn, "M_")}
    missing = [f.name for i, f in enumerate(fields.MUSCLE) if i not in offsets]
    assert not missing, f"declared muscle fields the stage never writes: {missing}"


def test_the_loop_writes_every_loop_field() -> None:
    """The controller's and the loop's record stores cover the table's loop fields."""
    offsets: set[int] = set()
    for module in (controller, loop):
        assert module.__file__ is not None
        tree = ast.parse(Path(module.__file__).read_text())
        offsets |= {getattr(module, n) for n in _stored(tree, "I_")}
    missing = [f.name for i, f in enumerate(fields.LOOP) if i not in offsets]
    assert not missing, f"declared loop fields nothing writes: {missing}"


def test_the_ros2_schemas_are_the_table() -> None:
    """The schema text each recording holds, parsed by mcap_ros2's own (rosidl) parser:
    exactly the table's fields, in order, with the table's types."""
    schemas = {name: data for name, enc, data in record_schemas() if enc == "ros2msg"}
    muscle = parse_message_string("pamd_msgs", "MuscleState",
                                  schemas[cdr.MUSCLE_SCHEMA_NAME].decode())
    loop = parse_message_string("pamd_msgs", "LoopTiming",
                                schemas[cdr.LOOP_SCHEMA_NAME].decode())
    assert [(f.name, f.type.type) for f in muscle.fields] == [
        (f.name, f.type) for f in fields.muscle_message()]
    assert [(f.name, f.type.type) for f in loop.fields] == [
        (f.name, f.type) for f in fields.LOOP]
    # and pamd's own reader of older files reads the same back
    assert cdr.parse_flat_schema(schemas[cdr.LOOP_SCHEMA_NAME].decode()) == cdr.loop_fields()
    assert "# bar: measured pressure" in schemas[cdr.MUSCLE_SCHEMA_NAME].decode()


def test_the_export_tables_are_the_table() -> None:
    for f in fields.BY_NAME.values():
        assert view_fields.unit_of(f.name) == f.unit
        assert view_fields.DESCRIPTIONS[f.name] == f.description
    assert view_fields.MUSCLE_COLUMNS[:2 + len(fields.MUSCLE)] == tuple(
        f.name for f in fields.muscle_message())
    assert {f.name: m for f, m in fields.FLAG_MEANINGS.items()} == {
        n: m for n, m in view_fields.FLAG_MEANINGS.items() if n not in FLAG_NAMES}
    assert view_fields.unit_of("an_old_column_bar") == "bar"  # older recordings' columns


def test_the_foxglove_layout_plots_the_tables_fields() -> None:
    layout = build_layout("rig", ["m1"])["configById"]
    for panel in PANELS:
        paths = [s["value"] for s in layout[f"Plot!m1-{panel}"]["paths"]]
        declared = [f"/pamd/rig/state/m1.{f.name}" for f in fields.MUSCLE if f.plot == panel]
        assert paths == declared and paths
    assert {f.plot for f in fields.MUSCLE if f.plot} == set(PANELS)


def test_a_bad_table_is_refused_at_import(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fields, "DERIVED", (*fields.DERIVED, fields.Field(
        "load_kg", "kg", "float64", "twice")))
    with pytest.raises(ValueError, match="declared twice"):
        fields.check_table()
    monkeypatch.setattr(fields, "DERIVED", (fields.Field("x", "kg", "float33", "bad"),))
    monkeypatch.setattr(fields, "BY_NAME", {"x": fields.DERIVED[0]})
    with pytest.raises(ValueError, match="float33"):
        fields.check_table()

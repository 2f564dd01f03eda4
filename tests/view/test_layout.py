"""The shipped Foxglove layout: it is what the generator writes for config/sim.yaml, and
every message path in it names a topic and a field of a real recording (the live view
serves the same channels and schemas: test_live), so it works on both."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from pamd.client.layout import build_layout, layout_json, main
from pamd.wire.record.cdr import parse_flat_schema

from .conftest import Recorded

SHIPPED = Path(__file__).resolve().parents[2] / "config" / "foxglove" / "pamd-layout.json"


def paths_of(layout: dict[str, Any]) -> list[str]:
    out = []
    for panel in layout["configById"].values():
        out += [p["value"] for p in panel.get("paths", [])]
        if "topicPath" in panel:
            out.append(panel["topicPath"])
    return out


def test_the_shipped_layout_is_the_generated_one(tmp_path: Path) -> None:
    assert SHIPPED.read_text() == layout_json("sim", ["m1"])
    out = tmp_path / "layout.json"
    assert main(["--out", str(out)]) == 0  # the built-in sim config
    assert out.read_text() == SHIPPED.read_text()


def test_every_path_names_a_recorded_topic_and_field(recorded: Recorded) -> None:
    with open(recorded.file, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    fields: dict[str, set[str] | None] = {}
    for c in summary.channels.values():
        s = summary.schemas[c.schema_id]
        flat = parse_flat_schema(s.data.decode()) if s.encoding == "ros2msg" else None
        fields[c.topic] = {n for n, _t in flat} if flat else None
    layout = json.loads(SHIPPED.read_text())
    paths = paths_of(layout)
    assert len(paths) >= 10
    for p in paths:
        topic, _, field = p.partition(".")
        assert topic in fields, p
        if field:
            assert field in (fields[topic] or set()), p
    # and every panel is placed in the layout tree
    placed = json.dumps(layout["layout"])
    assert all(f'"{pid}"' in placed for pid in layout["configById"])


def test_several_muscles_get_a_tab_each() -> None:
    lay = build_layout("bench", ["left", "right"])
    tabs = lay["configById"]["Tab!pamd-muscles"]["tabs"]
    assert [t["title"] for t in tabs] == ["left", "right"]
    assert "/pamd/bench/state/right.force_n" in paths_of(lay)

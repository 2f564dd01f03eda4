"""The file read by an implementation the writer did not come from: the TypeScript
reader `@mcap/core` under Node (tests/js/read_mcap.js), through the summary and
indexes as Foxglove reads it and again as a CRC-checked stream, with its own CDR
decoder working from the schema text."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS, TickLayout

from .conftest import same

JS = Path(__file__).resolve().parents[1] / "js"


def node_reader() -> list[str]:
    node = shutil.which("node")
    if node is None:
        pytest.fail("node is not installed (the independent MCAP reader runs under it): "
                    "run .ci/setup-tests, or apt-get install nodejs npm", pytrace=False)
    if not (JS / "node_modules" / "@mcap" / "core").is_dir():
        pytest.fail("tests/js/node_modules missing: run .ci/setup-tests, or "
                    "`npm ci --prefix tests/js`", pytrace=False)
    return [node, str(JS / "read_mcap.js")]


def test_typescript_reader_sees_every_tick_and_field(recorded_run: Any) -> None:
    cmd = node_reader()
    run = recorded_run(duration_s=1.0, profile={"kind": "sine", "min_bar": 1.0,
                                                "max_bar": 2.0, "freq_hz": 0.5})
    out = subprocess.run([*cmd, run.files[0]], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    n = len(run.cap.rows)
    ch = d["channels"]
    assert ch["/pamd/sim/state/m1"]["count"] == n and ch["/pamd/sim/loop"]["count"] == n
    assert ch["/pamd/sim/state/m1"]["fields"] == ["tick", "t_s", *MUSCLE_FIELDS]
    assert ch["/pamd/sim/loop"]["fields"] == list(LOOP_FIELDS)
    assert ch["/pamd/sim/events"]["schema_encoding"] == "jsonschema"
    assert d["stream_done"] is True
    assert d["stream_counts"]["/pamd/sim/state/m1"] == n
    layout = TickLayout(["m1"])
    state = d["messages"]["/pamd/sim/state/m1"]
    loop = d["messages"]["/pamd/sim/loop"]
    assert len(state) == n and len(loop) == n
    for k, row in enumerate(run.cap.rows):
        rec = layout.as_dict(row)
        vals = state[k][1]
        assert vals[0] == k and same(vals[1], row[1])
        for i, name in enumerate(MUSCLE_FIELDS):
            assert same(vals[2 + i], rec["m1"][name]), (k, name)
        for i, name in enumerate(LOOP_FIELDS):
            assert same(loop[k][1][i], rec[name]), (k, name)
    kinds = [b["kind"] for _t, b in d["messages"]["/pamd/sim/events"]]
    assert kinds.count("command") == 1 and "transition" in kinds
    assert d["metadata"]["pamd"]["note"] == "test note"
    assert [a["text"] for a in d["attachments"] if a["name"] == "sim.yaml"] == [
        run.daemon.cfg.text]

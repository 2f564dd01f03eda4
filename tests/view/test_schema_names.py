"""MCAP schema names: every schema a recording carries is `pamd_msgs/msg/...`, and a
recording made before the event schema was renamed (`pamd_msgs/Event`) still reads,
with `pamd.open_recording` and the training data reader alike."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap.writer import Writer

import pamd
from pamd.models.data.recordings import read_runs
from pamd.wire.record.cdr import EVENT_SCHEMA_NAME

from .conftest import Recorded

OLD_EVENT_SCHEMA_NAME = "pamd_msgs/Event"


def schema_names(path: Path) -> set[str]:
    with open(path, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    return {s.name for s in summary.schemas.values()}


def with_old_event_name(src: Path, dst: Path) -> None:
    """`src` rewritten record by record, its event schema under the old name."""
    with open(src, "rb") as fh, open(dst, "wb") as out:
        reader = make_reader(fh)
        w = Writer(out)
        w.start(profile="", library="test: the old schema name")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, ch, msg in reader.iter_messages():
            assert schema is not None
            if schema.id not in schemas:
                name = OLD_EVENT_SCHEMA_NAME if schema.name == EVENT_SCHEMA_NAME else schema.name
                schemas[schema.id] = w.register_schema(name, schema.encoding, schema.data)
            if ch.id not in channels:
                channels[ch.id] = w.register_channel(ch.topic, ch.message_encoding,
                                                     schemas[schema.id], dict(ch.metadata))
            w.add_message(channels[ch.id], msg.log_time, msg.data, msg.publish_time,
                          msg.sequence)
        for m in reader.iter_metadata():
            w.add_metadata(m.name, dict(m.metadata))
        for a in reader.iter_attachments():
            w.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        w.finish()


def test_every_schema_is_pamd_msgs_msg(recorded: Recorded) -> None:
    assert schema_names(recorded.file) == {"pamd_msgs/msg/MuscleState",
                                           "pamd_msgs/msg/LoopTiming", "pamd_msgs/msg/Event"}


def test_a_recording_with_the_old_event_schema_name_reads_the_same(
        recorded: Recorded, tmp_path: Path) -> None:
    old = tmp_path / "before-the-rename.mcap"
    with_old_event_name(recorded.file, old)
    assert OLD_EVENT_SCHEMA_NAME in schema_names(old)
    new_rec, old_rec = pamd.open_recording(recorded.file), pamd.open_recording(old)
    assert len(old_rec.events) == len(new_rec.events) > 0
    assert [(e.kind, e.t_s) for e in old_rec.events] == [(e.kind, e.t_s)
                                                         for e in new_rec.events]
    for name in new_rec["m1"].names:
        assert np.array_equal(old_rec["m1"][name], new_rec["m1"][name], equal_nan=True)
    (new_run,), (old_run,) = read_runs([str(recorded.file)]), read_runs([str(old)])
    assert old_run.events == new_run.events and len(old_run.events) > 0
    assert np.array_equal(old_run.t_s, new_run.t_s)

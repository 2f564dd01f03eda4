"""`pamd.open_recording` on real recordings: every tick and field as an independent
ROS 2 decoder reads them, states and modes as names, units, events and metadata; a
collection joined step by step with each step's load; a truncated file read up to its
last complete chunk, and said so; a file that is not a recording refused."""

from __future__ import annotations

import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

import pamd
from pamd.wire.tick import MUSCLE_FIELDS

from .conftest import Recorded


def independent(path: Path, topic: str) -> list[dict[str, float]]:
    """The topic's messages decoded by mcap_ros2 (not pamd's decoder)."""
    out = []
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _s, _c, _m, msg in reader.iter_decoded_messages(topics=[topic]):
            out.append({f: getattr(msg, f) for f in ("tick", "t_s", *MUSCLE_FIELDS)})
    return out


def test_a_recorded_run_as_arrays_with_names_and_units(recorded: Recorded) -> None:
    rec = pamd.open_recording(recorded.file)
    assert rec.complete and rec.warnings == []
    assert list(rec.muscles) == ["m1"] and rec.rig_id == "sim" and rec.rate_hz == 1000.0
    m1 = rec["m1"]
    n = recorded.summary["ticks"]
    assert len(m1) == n == len(rec.loop["tick"])
    ref = independent(recorded.file, "/pamd/sim/state/m1")
    assert len(ref) == n
    for name in ("tick", "t_s", *MUSCLE_FIELDS):
        want = np.array([r[name] for r in ref], dtype=np.float64)
        np.testing.assert_array_equal(m1[name].astype(np.float64), want, err_msg=name)
    assert m1["tick"].dtype == np.int64 and m1["pressure_bar"].dtype == np.float64
    # the supervisor's states as names, from the loop topic, tick by tick
    states = m1.states()
    assert states[0] in ("STARTING", "IDLE") and "RUNNING" in set(states)
    assert states[-1] == recorded.summary["final_state"]
    np.testing.assert_array_equal(m1["state"], rec.loop["state"])
    assert set(m1.modes()) == {"pressure"}
    assert m1.unit("pressure_bar") == "bar" and m1.unit("force_n") == "N"
    assert m1.unit("velocity_mm_s") == "mm/s" and m1.unit("contraction") == "1"
    assert (m1["load_kg"] == 30.0).all()  # config/sim.yaml's hanging load
    # the run tracked its sine: pressure follows the setpoint while running
    run = states == "RUNNING"
    err = np.abs(m1["pressure_bar"][run] - m1["setpoint_bar"][run])
    assert err.mean() < 0.05
    kinds = [e.kind for e in rec.events]
    assert "transition" in kinds and "command" in kinds
    assert rec.metadata["pamd"]["rig_id"] == "sim"
    assert math.isclose(rec.duration_s, (n - 1) / 1000.0, rel_tol=1e-9)


def test_a_recorded_run_as_a_dataframe(recorded: Recorded) -> None:
    rec = pamd.open_recording(str(recorded.file))
    df = rec.frame()
    m1 = rec["m1"]
    assert list(df.columns) == list(m1.columns) and len(df) == len(m1)
    assert str(df["state"].dtype) == "category" and "RUNNING" in set(df["state"])
    assert list(df["mode"].cat.categories) == ["pressure", "length_force", "position"]
    assert df.attrs["units"]["pressure_bar"] == "bar"
    np.testing.assert_array_equal(df["force_n"].to_numpy(), m1["force_n"])
    ev = rec.events_frame()
    assert len(ev) == len(rec.events) and set(ev["kind"]) >= {"transition", "command"}


def test_a_collection_is_joined_step_by_step_with_its_loads(collection: Path) -> None:
    rec = pamd.open_recording(collection)
    assert [f.step for f in rec.files] == ["load-15kg", "load-40kg"]
    assert [f.load_kg for f in rec.files] == [15.0, 40.0]
    m1 = rec["m1"]
    assert len(m1) == sum(f.ticks for f in rec.files)
    first = m1["file"] == 0
    assert (m1["load_kg"][first] == 15.0).all() and (m1["load_kg"][~first] == 40.0).all()
    # the last step's file keeps the rest of the run after the plan (segment 0)
    assert set(m1["segment"][first]) == {1} and m1["segment"][~first][0] == 2
    assert set(m1["segment"][~first]) <= {2, 0}
    # the heavier load stretches the muscle: longer at the same pressure
    assert np.median(m1["length_mm"][~first]) > np.median(m1["length_mm"][first])


def test_a_truncated_file_gives_what_is_there_and_says_so(recorded: Recorded,
                                                          tmp_path: Path) -> None:
    cut = tmp_path / "cut.mcap"
    shutil.copy(recorded.file, cut)
    size = cut.stat().st_size
    with open(cut, "r+b") as fh:
        fh.truncate(size // 2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = pamd.open_recording(cut)
    assert any(issubclass(w.category, pamd.RecordingIncomplete) for w in caught)
    assert not rec.complete and "unfinished recording" in rec.warnings[0]
    assert "pamd recover" in rec.warnings[0]
    full = pamd.open_recording(recorded.file)["m1"]
    part = rec["m1"]
    assert 0 < len(part) < len(full)
    np.testing.assert_array_equal(part["pressure_bar"], full["pressure_bar"][:len(part)])


def test_what_is_not_a_recording_is_refused_clearly(tmp_path: Path) -> None:
    junk = tmp_path / "notes.mcap"
    junk.write_text("hello")
    with pytest.raises(pamd.RecordingError, match="not an MCAP file"):
        pamd.open_recording(junk)
    with pytest.raises(pamd.RecordingError, match="no such file"):
        pamd.open_recording(tmp_path / "missing.mcap")
    (tmp_path / "empty").mkdir()
    with pytest.raises(pamd.RecordingError, match="no .mcap files"):
        pamd.open_recording(tmp_path / "empty")


def test_the_public_api_is_what_pamd_lists() -> None:
    for name in pamd.__all__:
        assert getattr(pamd, name) is not None
    assert set(dir(pamd)) == set(pamd.__all__)
    with pytest.raises(AttributeError):
        pamd.Daemon  # noqa: B018 - internals are not promised


def test_the_three_ways_of_reading_give_the_same_columns(
        recorded: Recorded, monkeypatch: pytest.MonkeyPatch) -> None:
    """A file is read by its message indexes (pamd's files), else by walking each chunk's
    records, else (no chunk index: an unfinished file) message by message: the columns
    and events are the same each way, and an index that misses a message is not trusted
    (the walk reads it)."""
    from pamd.wire.record import files, tables

    def columns() -> tables.Columns:
        return tables.read_columns(str(recorded.file))

    walked: list[int] = []
    walk = tables.record_starts
    monkeypatch.setattr(tables, "record_starts",
                        lambda *a: walked.append(1) or walk(*a))
    indexed = columns()
    assert not walked  # pamd writes message indexes: no walk needed
    with monkeypatch.context() as m:
        m.setattr(tables, "indexed_starts", lambda index: None)
        by_walk = columns()
    assert walked
    find = tables.indexed_starts
    with monkeypatch.context() as m:  # an index that lists all but one message a chunk
        m.setattr(tables, "indexed_starts", lambda index: find(index)[:-1])
        short_index = columns()
    with monkeypatch.context() as m:
        m.setattr(files, "iter_chunk_data", lambda path: None)
        one_by_one = columns()
    n = recorded.summary["ticks"]
    assert len(indexed.muscles["m1"]["tick"]) == len(indexed.loop["tick"]) == n
    for other in (by_walk, short_index, one_by_one):
        assert list(other.loop) == list(indexed.loop)
        for name, col in indexed.loop.items():
            np.testing.assert_array_equal(other.loop[name], col, err_msg=name)
        assert list(other.muscles) == ["m1"]
        for name, col in indexed.muscles["m1"].items():
            assert other.muscles["m1"][name].dtype == col.dtype
            np.testing.assert_array_equal(other.muscles["m1"][name], col, err_msg=name)
        assert other.events == indexed.events


def test_states_and_modes_are_named_tick_by_tick(recorded: Recorded) -> None:
    from pamd.client import field_info as fields

    m1 = pamd.open_recording(recorded.file)["m1"]
    codes = m1["state"].copy()
    codes[:3] = np.nan  # a tick the loop topic did not have
    m1.columns["state"] = codes
    assert list(m1.states()) == [fields.state_name(c) for c in codes]
    assert list(m1.modes()) == [fields.mode_name(c) for c in m1["mode"]]

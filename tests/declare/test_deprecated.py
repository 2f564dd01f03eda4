"""The old names pamd still serves (issue 41 item 3; `pamd.wire.declare.deprecated`):
the tick flag's alias is the same bit under both names, the status's old keys carry
the new ones' values, the exports list both flag names, and the fields reference says
what each became and when it goes. (calibration.yaml's old key:
tests/safety/test_datums.py; the status from a running daemon: tests/net.)"""

from __future__ import annotations

import pytest

from pamd.client import field_info
from pamd.wire.declare import deprecated, fields, fields_doc
from pamd.wire.status import MUSCLE_STATUS_FIELDS, with_old_keys
from pamd.wire.tick import Flag


def test_the_old_flag_name_is_the_same_bit() -> None:
    assert Flag.NOT_REFERENCED is Flag.NO_LENGTH_DATUM and Flag["NOT_REFERENCED"] == 128
    assert int(Flag.NO_LENGTH_DATUM) == 1 << 7  # the recorded bit never moves
    assert Flag(128).name == "NO_LENGTH_DATUM"  # what a reader of any recording is told
    assert [f.name for f in Flag].count("NO_LENGTH_DATUM") == 1
    assert "NOT_REFERENCED" not in [f.name for f in Flag]  # listed once, by its new name
    # the exports' flag tables (MATLAB flag_bits, the CSV sidecar) name both
    assert field_info.FLAG_BITS["NOT_REFERENCED"] == field_info.FLAG_BITS["NO_LENGTH_DATUM"]
    assert "NO_LENGTH_DATUM" in field_info.FLAG_MEANINGS["NOT_REFERENCED"]


def test_the_old_status_keys_carry_the_new_ones_values() -> None:
    muscle = {"has_length_datum": False, "mode": "pressure",
              "datums": {"has_length_datum": False, "homed_at": None,
                         "tared_at": "2026-01-02T03:04:05+0000", "length_offset_mm": 1.5,
                         "force_offset_n": -3.0}}
    out = with_old_keys(muscle)
    assert list(out)[:3] == list(muscle)  # the new keys first, untouched
    assert out["referenced"] is False
    assert out["references"] == {"length_referenced": False, "homed_at": None,
                                 "tared_at": "2026-01-02T03:04:05+0000",
                                 "length_offset_mm": 1.5, "force_offset_n": -3.0}
    # declared: last in the muscle's status, after their replacements
    n = len(deprecated.MUSCLE_STATUS_KEYS)
    assert MUSCLE_STATUS_FIELDS[-n:] == tuple(deprecated.MUSCLE_STATUS_KEYS)
    assert set(deprecated.MUSCLE_STATUS_KEYS.values()) <= set(MUSCLE_STATUS_FIELDS[:-n])


def test_the_fields_reference_says_each_old_name_and_when_it_goes() -> None:
    text = fields_doc.generate().split("## Old names (deprecated)", 1)[1]
    assert f"go in pamd {deprecated.REMOVED_IN}" in text
    for o in deprecated.OLD_NAMES:
        assert f"| `{o.old}` | `{o.new}` |" in text


def test_an_old_name_left_out_of_the_table_is_found(monkeypatch: pytest.MonkeyPatch) -> None:
    """The declaration's own checks fire: an old key with no description, a flag alias
    missing from `Flag`."""
    monkeypatch.setitem(deprecated.DATUM_KEYS, "homed", "homed_at")
    with pytest.raises(ValueError, match="old names"):
        deprecated.check()
    monkeypatch.delitem(deprecated.DATUM_KEYS, "homed")
    deprecated.check()  # quiet when the table is whole
    monkeypatch.setitem(deprecated.FLAG_NAMES, "NOT_STALE", "STALE")
    with pytest.raises(ValueError, match="Flag.NOT_STALE"):
        fields.check_table()


def test_pamd_status_prints_the_datums_of_a_daemon_new_or_older(
        capsys: pytest.CaptureFixture[str]) -> None:
    """`pamd status` reads the new keys, and an older daemon's old ones the same."""
    from pamd.client.cli.net import print_status

    datums = {"has_length_datum": True, "homed_at": "2026-01-02T03:04:05", "tared_at": None,
              "length_offset_mm": 1.5, "force_offset_n": 0.0}
    new = {"has_length_datum": True, "datums": datums}
    older = with_old_keys(new)
    del older["has_length_datum"], older["datums"]
    for muscle in (with_old_keys(new), older):
        print_status({"rig_id": "sim", "state": "IDLE", "muscles": {"m1": muscle}})
        assert "length datum yes (homed 2026-01-02T03:04:05, tared -)" in (
            capsys.readouterr().out)

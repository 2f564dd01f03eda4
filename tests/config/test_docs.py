"""The committed config reference is generated from the schema and must be current."""

from __future__ import annotations

from pathlib import Path

from pamd.config.docs import generate

DOC = Path(__file__).resolve().parents[2] / "docs" / "config-reference.md"


def test_config_reference_is_current() -> None:
    assert DOC.read_text() == generate(), (
        "docs/config-reference.md is stale: run `python -m pamd.config.docs > "
        "docs/config-reference.md`")


def test_reference_lists_every_key_with_unit() -> None:
    text = generate()
    for key in ("`loop.rate_hz`", "`safety.signal_timeout_s`", "`control.pid.ki_per_s`",
                "`muscles[].signals.valve.raw_max`", "`options.muscles[].friction_n_per_bar`"):
        assert key in text
    row = next(ln for ln in text.splitlines() if ln.startswith("| `loop.rate_hz`"))
    assert "| Hz |" in row and "`1000.0`" in row

"""The run's bytecode (tests/conftest.py's pytest_configure): every module of pamd and
the drivers compiled, whole, before the processes the tests start import it."""

from __future__ import annotations

import importlib.util
import marshal
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.skipif(sys.dont_write_bytecode, reason="this run writes no bytecode")
def test_every_module_was_compiled_whole_before_the_tests() -> None:
    sources = [p for package in ("pamd", "drivers") for p in (ROOT / package).rglob("*.py")]
    assert len(sources) > 200
    for source in sources:
        pyc = Path(importlib.util.cache_from_source(str(source)))
        assert pyc.exists(), f"{source.relative_to(ROOT)} has no bytecode"
        data = pyc.read_bytes()
        code = marshal.loads(data[16:])  # a file cut short: "marshal data too short"
        assert code.co_filename.endswith(source.name)

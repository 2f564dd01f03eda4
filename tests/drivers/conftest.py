"""Fixtures of the driver tests (helpers live in pamd.emulate.testing)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from pamd.emulate.testing import AioThread


@pytest.fixture
def aio() -> Iterator[AioThread]:
    t = AioThread()
    yield t
    t.stop()

"""Shared helpers of the simulated-rig tests: a `SimDriver` on a virtual clock."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.sim.rig import Rig


@pytest.fixture(scope="session")
def make_rig() -> Callable[..., Rig]:
    return Rig

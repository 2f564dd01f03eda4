"""The tick's golden hashes: four scenarios stepped on the harness (virtual clock), every
tick record hashed, pinned. A change that is meant to keep behaviour (a refactor, a
speed-up, a move) keeps these equal; a change that is meant to alter a scenario says
so in its commit and re-pins that scenario alone.

What is hashed does not depend on the CPU or the numpy build: the tick is plain
CPython float arithmetic (IEEE 754 doubles, the same on every x86-64 and ARM64), and
each value is rounded to 9 significant digits before hashing, so that a last-bit
difference from another libm or a SIMD path of a library would have to cross a
rounding boundary to show (about one value in 10^7 per last-bit difference). The two
fields that measure the host (`wake_latency_s`, `compute_s`) are left out.

Re-pin after an intended change with `python tests/test_golden.py` (prints the four).
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest

from pamd.config import load_config
from pamd.loop.harness import Harness
from pamd.wire.tick import LOOP_FIELDS

ROOT = Path(__file__).resolve().parents[1]
HOST_FIELDS = {LOOP_FIELDS.index("wake_latency_s"), LOOP_FIELDS.index("compute_s")}
DIGITS = 9
SECONDS = 6.0
EVENT_S = 4.5

GOLDEN = {
    "regulator": "f9fa59669eae97f4",
    "onoff": "47be7b4a9ea07031",
    "harsh": "078eadb721fb6f8a",
    "fault": "078223595e67c018",
}


def _no_event(h: Harness) -> None:
    return None


def _pressure_dies(h: Harness) -> None:
    h.sim.inject_fault("m1", "pressure", "dead")


#: name -> (config file, what happens at EVENT_S)
SCENARIOS: dict[str, tuple[str, Callable[[Harness], None]]] = {
    "regulator": ("config/sim.yaml", _no_event),
    "onoff": ("config/sim-onoff.yaml", _no_event),
    "harsh": ("config/sim-harsh.yaml", _no_event),
    "fault": ("config/sim.yaml", _pressure_dies),
}


def _row_text(rec: Sequence[float]) -> str:
    return ",".join("-" if i in HOST_FIELDS else format(v, f".{DIGITS}g")
                    for i, v in enumerate(rec))


def run_hash(name: str) -> str:
    """The scenario's hash: a 1-5 bar sine at 0.25 Hz from rest (its lead-in ramp
    first) for SECONDS of rig time, its event at EVENT_S."""
    config, event = SCENARIOS[name]
    h = Harness(load_config(str(ROOT / config), {"loop": {"clock": "virtual"}}))
    digest = hashlib.sha256()
    put = h.sink.put

    def hashed(rec: Sequence[float]) -> None:
        digest.update(_row_text(rec).encode())
        put(rec)

    h.sink.put = hashed  # type: ignore[method-assign]  # the test's tap on the sink
    verdict = h.cmd("profile", kind="sine", min_bar=1.0, max_bar=5.0, freq_hz=0.25,
                    cycles=10)
    assert verdict.get("ok", True) is not False, verdict
    h.step(EVENT_S)
    event(h)
    h.step(SECONDS - EVENT_S)
    return digest.hexdigest()[:16]


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_the_tick_keeps_its_golden_hash(name: str) -> None:
    assert run_hash(name) == GOLDEN[name], (
        f"scenario {name!r}: the tick's records changed. If the change is meant to "
        "alter it, say so in the commit and re-pin with `python tests/test_golden.py`")


def test_the_hash_sees_a_change_in_the_last_pinned_digit() -> None:
    """The rounding keeps what matters: values that differ in the 9th significant digit
    give other rows, values that differ beyond it the same."""
    assert _row_text([1.0] * 12) != _row_text([1.0] * 11 + [1.00000001])
    assert _row_text([1.0] * 12) == _row_text([1.0] * 11 + [1.0000000000001])


if __name__ == "__main__":
    for n in sorted(SCENARIOS):
        sys.stdout.write(f'    "{n}": "{run_hash(n)}",\n')

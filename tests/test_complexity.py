"""Small functions (issue 42), measured by radon's cyclomatic complexity (the number of
independent paths through a function: 1 + its branches, loops, boolean operators and
handlers): no function in pamd/ or drivers/ over 20, and none on the tick path over 15.

The tick path is what a tick runs, found by running it: the simulated rig stepped
through the scenarios below (a pressure profile and a fault's entry, position mode
with a model, its adaptation and ILC, on/off valves positioning and following a
profile, the safety chain opening and the air held, the deadman, a plan's steps, the
tuning runs' relay and valve pulse) and the loop itself on the virtual clock with a
command waiting, every Python function they call traced (`sys.setprofile`). A
function a tick newly calls is on the path without anyone listing it.

The bounds: nothing on the tick path over 15, nothing anywhere in pamd/ and drivers/
over 20 (the tick's own code, `TICK_OWNED`, is also checked on its own so its failure
names the tick). A failure lists the offenders, worst first.

This replaces the 300-line cap on a class (issue 26): a class is as long as its one
job needs, and no class is split across files to meet a count; what stays small is
each function.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from types import CodeType, FrameType
from typing import Any

from radon.complexity import cc_visit
from radon.visitors import Function

ROOT = Path(__file__).resolve().parents[1]
MAX_COMPLEXITY = 20
MAX_TICK_COMPLEXITY = 15
MODEL = ROOT / "tests" / "models" / "fixtures" / "anfis-v1.json"

#: On the tick path but not run by the traced scenarios, which start no io process: the
#: io link's sink, which the summary hands every record (`pamd.loop.io_link.RingSink`).
UNTRACED_TICK_PATH = ("pamd/loop/io_link.py:RingSink.put",)

#: The tick's own code (issue 42 item 1: the tick path and what builds and commands it):
#: nothing here is over MAX_COMPLEXITY, whether a tick runs it or not.
TICK_OWNED = ("pamd/loop/control/", "pamd/loop/safety/", "pamd/loop/control/controller.py",
              "pamd/wire/tick.py",
              "pamd/loop/loop.py", "pamd/loop/io_link.py", "pamd/loop/experiment/sequencer.py",
              "drivers/sim.py", "drivers/sim_chain.py", "drivers/sim_faults.py",
              "pamd/sim/")

def _flat(fn: Function, prefix: str = "") -> Iterator[tuple[str, int, int]]:
    name = prefix + (f"{fn.classname}." if fn.classname else "") + fn.name
    yield name, fn.lineno, fn.complexity
    for inner in fn.closures:
        yield from _flat(inner, name + ".")


@functools.cache
def complexities() -> dict[tuple[str, str], tuple[int, int]]:
    """(file relative to the checkout, qualified name) -> (line, complexity) of every
    function and method in pamd/ and drivers/ (a class's methods by their own)."""
    out: dict[tuple[str, str], tuple[int, int]] = {}
    for base in ("pamd", "drivers"):
        for path in sorted((ROOT / base).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            for block in cc_visit(path.read_text()):
                if isinstance(block, Function):
                    for name, line, cc in _flat(block):
                        out[(rel, name)] = (line, cc)
    return out


def _named(over: dict[tuple[str, str], int]) -> dict[str, int]:
    return {f"{rel}:{name}": cc for (rel, name), cc in over.items()}


def _listed(over: dict[str, int]) -> str:
    """The offenders, worst first, each `file:line name (complexity)`."""
    lines = {f"{rel}:{name}": line for (rel, name), (line, _) in complexities().items()}
    rows = []
    for key, cc in sorted(over.items(), key=lambda kv: -kv[1]):
        rel, name = key.split(":", 1)
        rows.append(f"  {rel}:{lines[key]} {name} ({cc})")
    return "\n".join(rows)


def over(limit: int, where: tuple[str, ...] = ("pamd/", "drivers/")) -> dict[str, int]:
    """`file:name` -> complexity of every function in `where` over `limit`."""
    return _named({k: cc for k, (_, cc) in complexities().items()
                   if cc > limit and k[0].startswith(where)})


def test_nothing_on_the_tick_path_is_over_15() -> None:
    found = tick_path_over(MAX_TICK_COMPLEXITY)
    assert not found, (f"on the tick path, split these (cyclomatic complexity over "
                       f"{MAX_TICK_COMPLEXITY}):\n{_listed(found)}")


def test_nothing_of_the_ticks_own_code_is_over_20() -> None:
    found = over(MAX_COMPLEXITY, TICK_OWNED)
    assert not found, (f"split these (cyclomatic complexity over {MAX_COMPLEXITY}):\n"
                       f"{_listed(found)}")


def test_no_function_is_over_20() -> None:
    found = over(MAX_COMPLEXITY)
    assert not found, (f"{len(found)} functions to split (cyclomatic complexity over "
                       f"{MAX_COMPLEXITY}):\n{_listed(found)}")


def test_the_checks_see_a_branchy_function_and_the_tick_path() -> None:
    """The checks themselves: radon counts a function's branches as this test reads
    them, and the traced tick path holds the tick's own stages and the loop's."""
    src = "def f(a):\n" + "".join(f"    if a == {i}:\n        return {i}\n"
                                 for i in range(MAX_COMPLEXITY)) + "    return -1\n"
    (fn,) = cc_visit(src)
    assert isinstance(fn, Function) and fn.complexity == MAX_COMPLEXITY + 1
    traced = tick_path()
    for must in ("pamd/loop/control/controller.py:RigController.tick",
                 "pamd/loop/control/muscle.py:MuscleController.write",
                 "pamd/loop/control/setpoint.py:SafeRamp.update",
                 "pamd/loop/control/length_control.py:LengthControl.step",
                 "pamd/loop/control/actuation.py:OnOffActuation.update",
                 "pamd/loop/control/adapt.py:Adaptation.update",
                 "pamd/loop/loop.py:Loop._run", "pamd/loop/loop.py:tick_once",
                 "pamd/loop/experiment/sequencer.py:Sequencer.tick"):
        assert must in traced, must


# -- the tick path, traced -------------------------------------------------------------
def _traced(run: Callable[[], None], into: set[CodeType]) -> None:
    def seen(frame: FrameType, event: str, arg: Any) -> None:  # Any: setprofile's hook
        if event == "call":
            into.add(frame.f_code)

    sys.setprofile(seen)
    try:
        run()
    finally:
        sys.setprofile(None)


def _harness(config: str, **changes: Any) -> Any:  # Any: pamd.loop.harness.Harness
    from pamd.config import load_config
    from pamd.loop.harness import Harness

    return Harness(load_config(str(ROOT / config), {
        "loop": {"clock": "virtual"}, "telemetry": {"enabled": False}, **changes}))


def _ok(verdict: dict[str, Any]) -> None:
    assert verdict.get("ok", True) is not False, verdict


def _scenarios(into: set[CodeType]) -> None:
    """Every scenario's ticks traced into `into` (what is set up between them is not)."""
    from pamd.loop.commands import Command, apply_command
    from pamd.loop.commands.tune_verbs import PulseArgs, RelayArgs
    from pamd.loop.control.feedforward import LoadedModel
    from tests.experiment.test_sequencer import start

    def steps(h: Any, seconds: float) -> None:
        _traced(lambda: h.step(seconds), into)

    h = _harness("config/sim.yaml")  # a pressure profile, a fault's entry, the safe ramp
    _ok(h.cmd("profile", kind="sine", min_bar=1.0, max_bar=5.0, freq_hz=0.25))
    steps(h, 0.2)
    h.sim.inject_fault("m1", "pressure", "jump", 1.0)
    steps(h, 0.2)
    h.rig.close()

    h = _harness("config/sim.yaml")
    cfg = h.cfg  # position mode with a model, its adaptation and ILC
    h.ctrl.muscles[0].swap_model(LoadedModel.read(str(MODEL), cfg.muscle("m1"),
                                                  cfg.limits["m1"]).feedforward())
    _ok(h.cmd("adapt", action="on"))
    _ok(h.cmd("mode", mode="position", ilc=True))
    _ok(h.cmd("profile", kind="sine", min_contraction=0.05, max_contraction=0.12,
              freq_hz=0.25))
    steps(h, 0.3)
    h.rig.close()

    h = _harness("config/sim-onoff.yaml")  # on/off valves: positioning, the PWM
    _ok(h.cmd("mode", mode="position", feedforward=False))
    _ok(h.cmd("setpoint", muscle="m1", length_mm=185.0))
    steps(h, 0.2)
    _ok(h.cmd("mode", mode="pressure"))
    _ok(h.cmd("setpoint", muscle="m1", bar=3.0))
    steps(h, 0.5)
    _ok(apply_command(h.ctrl, Command("pulse", PulseArgs("m1", "inflate", 0.05))))
    steps(h, 0.2)
    h.rig.close()

    h = _harness("config/sim-chain.yaml")  # the safety chain, the air held
    _ok(h.cmd("profile", kind="sine", min_bar=1.0, max_bar=5.0, freq_hz=0.25))
    steps(h, 0.1)
    h.sim.inject_fault("*", "safety_chain", "open")
    steps(h, 0.1)
    h.rig.close()

    h = _harness("config/sim.yaml")  # the relay test, the deadman
    _ok(h.cmd("setpoint", muscle="m1", bar=3.0))
    steps(h, 0.8)
    _ok(apply_command(h.ctrl, Command("relay", RelayArgs("m1", 3.0, 0.2, 0.02, 0.5))))
    steps(h, 0.3)
    _ok(h.cmd("setpoint", muscle="m1", bar=2.0, deadman_s=0.05))
    steps(h, 0.2)
    h.rig.close()

    h = _harness("config/sim.yaml")  # a plan's steps (the sequencer ticks in the loop)
    h.step(0.01)
    _ok(start(h, "name: p\nmuscle: m1\nsettle: {seconds: 0.1}\nprofile: {kind: sine, "
                 "min_bar: 1.0, max_bar: 2.0, freq_hz: 1.0, cycles: 1}\nsteps:\n"
                 "  - {name: a, load_kg: 30}\n"))
    steps(h, 1.0)
    h.rig.close()


def _loop(into: set[CodeType]) -> None:
    """The loop on the virtual clock, a command waiting, to its stop and safe state."""
    from collections import deque

    from pamd.loop.commands import parse_command
    from pamd.loop.loop import Loop

    h = _harness("config/sim.yaml")
    waiting = deque([parse_command("setpoint", {"muscle": "m1", "bar": 2.0})])

    class Queue:
        def poll(self) -> Any:  # Any: a Command, as pamd.wire.tick.Mailbox says
            return waiting.popleft() if waiting else None

    loop = Loop(h.cfg, h.ctrl, Queue())
    _traced(lambda: loop.run(0.3), into)
    h.rig.close()


@functools.cache
def tick_path() -> frozenset[str]:
    """`file:qualified name` of every function of pamd/ and drivers/ a tick runs (and
    UNTRACED_TICK_PATH)."""
    codes: set[CodeType] = set()
    _scenarios(codes)
    _loop(codes)
    by_file: dict[str, list[tuple[str, int]]] = {}
    for (rel, name), (line, _) in complexities().items():
        by_file.setdefault(rel, []).append((name, line))
    found = set(UNTRACED_TICK_PATH)
    for code in codes:
        try:
            rel = str(Path(code.co_filename).resolve().relative_to(ROOT))
        except ValueError:
            continue  # the standard library, numpy, ...
        for name, line in by_file.get(rel, ()):
            # the def's line, or its decorators' first (a property's)
            if name.rsplit(".", 1)[-1] == code.co_name and 0 <= line - code.co_firstlineno <= 5:
                found.add(f"{rel}:{name}")
    return frozenset(found)


def tick_path_over(limit: int) -> dict[str, int]:
    all_cc = _named({k: cc for k, (_, cc) in complexities().items()})
    return {k: all_cc[k] for k in tick_path() if all_cc[k] > limit}

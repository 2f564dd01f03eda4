"""What the rig does on the hardware safety chain's signals (one job of the rig
controller, `pamd.loop.control.controller`; the signals themselves: `pamd.loop.safety.chain`).

Read every tick, acted on along rare paths only past the first comparisons: the
chain open is an ESTOP and the supply lost a FAULT, each holding the air; the supply
out holds the integrators (no wind-up against a missing supply); the reset button
acknowledges a latched fault through the rig controller's restart interlock."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from pamd.loop.control.muscle import MuscleController
from pamd.loop.safety import Supervisor
from pamd.loop.safety.chain import SafetyChain
from pamd.wire.tick import Sink, State


class ChainResponse:
    """The rig's response to its safety chain (whether the air is out, last tick)."""

    def __init__(self, muscles: Sequence[MuscleController], supervisor: Supervisor,
                 sink: Sink, reset_latched: Callable[[str], str | None]) -> None:
        """`reset_latched`: the rig controller's acknowledgement (returns why not)."""
        self._muscles = muscles
        self._supervisor = supervisor
        self._sink = sink
        self._reset_latched = reset_latched
        self._air_out = False

    def respond(self, now: float, chain: SafetyChain) -> None:
        """The chain's signals, read this tick (not while STARTING)."""
        sup = self._supervisor
        air_out = chain.air_out
        if air_out != self._air_out:
            self._air_out = air_out
            for m in self._muscles:
                m.set_air_out(air_out)
            self._sink.event(now, "supply", {
                "state": "out" if air_out else "back", "supply_bar": chain.supply_bar,
                "safety_chain": chain.closed})
        why = chain.open_reason
        if why is not None:
            if sup.state != State.ESTOP:
                self._sink.event(now, "safety_chain", {"state": "open", "reason": why})
                for m in self._muscles:
                    m.stop_profile()
                sup.estop(now, why)
            self._hold_air()  # also under an ESTOP latched before: the air is cut
        elif chain.supply_reason is not None:
            if not sup.latched:
                sup.fault(now, chain.supply_reason)
            if sup.latched:
                self._hold_air()
        if chain.reset_pressed and sup.latched:
            refused = self._reset_latched("input")
            self._sink.event(now, "reset", {"by": "input", "ok": refused is None,
                                            "reason": refused or sup.reason})

    def _hold_air(self) -> None:
        for m in self._muscles:
            m.hold_air()

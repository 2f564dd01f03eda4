"""The physics behind the emulated rig: the `sim` driver's muscles (pamd.sim),
stepped in real time on their own thread, with the rig config's signal bindings
inverted so each emulated device knows what to show on which channel.

For an input signal `si = gain * raw + offset` the device shows
`raw = (si - offset) / gain`; for an output the device's raw value becomes
`gain * raw + offset` at the simulated regulator (or exhaust valve).
"""

from __future__ import annotations

import math
import os
import threading
import time
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig
from pamd.drivers.sim import SimDriver
from pamd.emulate.lateness import Lateness
from pamd.sim.options import SimMuscleOptions, SimOptions

STEP_S = 0.001


@dataclass(frozen=True)
class Binding:
    sim_index: int
    gain: float
    offset: float


class EmulatedPlant:
    """Simulated muscles of a rig config, and the map (driver, channel) -> signal."""

    def __init__(self, cfg: LoadedConfig, seed: int = 1,
                 loads_kg: dict[str, float] | None = None,
                 heartbeat_watchdog_s: float = 0.0) -> None:
        """`heartbeat_watchdog_s`: the safety relay watching the heartbeat output opens
        the chain when it stands still this long (0: no relay)."""
        loads_kg = loads_kg or {}
        muscles = tuple(
            SimMuscleOptions(name=m.name, nominal_length_mm=m.nominal_length_mm,
                             load_kg=loads_kg.get(m.name, m.load_kg), force_model=m.force_model,
                             actuation=m.actuation,
                             valve_on_delay_s=m.onoff.valve_on_delay_s,
                             valve_off_delay_s=m.onoff.valve_off_delay_s)
            for m in cfg.rig.muscles)
        # each simulated muscle of its rig muscle's type (a custom one with its map)
        options = SimDriver.bind_muscle_types(
            SimOptions(seed=seed, muscles=muscles, heartbeat_watchdog_s=heartbeat_watchdog_s),
            {f"{m.name}.pressure": cfg.muscle_type(m.name) for m in cfg.rig.muscles},
            os.path.dirname(os.path.abspath(cfg.path)))
        self.sim = SimDriver("emulated", options)
        self.sim.open(time.monotonic)
        self.inputs: dict[tuple[str, str], Binding] = {}
        self.outputs: dict[tuple[str, str], Binding] = {}
        for k, m in enumerate(cfg.rig.muscles):
            s = m.signals
            for j, sig in enumerate((s.pressure, s.force, s.length)):
                self.inputs[(sig.driver, sig.channel)] = Binding(3 * k + j, sig.gain, sig.offset)
            first = s.valve if s.valve is not None else s.inflate  # regulator or valve
            if first is not None:
                self.outputs[(first.driver, first.channel)] = Binding(2 * k, first.gain,
                                                                      first.offset)
            if s.exhaust is not None:
                self.outputs[(s.exhaust.driver, s.exhaust.channel)] = Binding(
                    2 * k + 1, s.exhaust.gain, s.exhaust.offset)
        self._bind_chain(cfg)
        self.lock = threading.Lock()
        self.steps = 0
        self.lateness = Lateness()  # of the physics steps against their 1 ms schedule
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _bind_chain(self, cfg: LoadedConfig) -> None:
        """The hardware safety chain's signals (`safety_chain`): the emergency-stop,
        supply and reset inputs show the simulated rig's own (`safety_chain`, `supply`,
        `reset`), the heartbeat output drives its heartbeat (and, with
        `heartbeat_watchdog_s`, the relay watching it)."""
        chain = cfg.rig.safety_chain
        for sig, sim_channel in ((chain.estop, "safety_chain"), (chain.supply, "supply"),
                                 (chain.reset, "reset")):
            if sig is not None:
                self.inputs[(sig.driver, sig.channel)] = Binding(
                    self.sim.input_index(sim_channel), sig.gain, sig.offset)
        hb = chain.heartbeat
        if hb is not None:
            self.outputs[(hb.driver, hb.channel)] = Binding(
                self.sim.output_index("heartbeat"), hb.gain, hb.offset)

    # -- the safety chain at the rig (tests, `pamd emulate` users) -----------------------------
    def open_chain(self) -> None:
        """An emergency stop pressed: the chain opens and cuts every muscle's supply."""
        with self.lock:
            self.sim.inject_fault("*", "safety_chain", "open")

    def close_chain(self) -> None:
        """The emergency stop released: the chain closes, the air returns."""
        with self.lock:
            self.sim.inject_fault("*", "safety_chain", "closed")

    def press_reset(self, pressed: bool = True) -> None:
        """The reset button at the rig, held while `pressed`."""
        with self.lock:
            self.sim.press_reset(pressed)

    def raw_input(self, driver: str, channel: str) -> float | None:
        """What the device carrying (driver, channel) shows now (None: not bound)."""
        b = self.inputs.get((driver, channel))
        if b is None:
            return None
        si = self.sim.in_values[b.sim_index]
        if si != si:
            return None
        return (si - b.offset) / b.gain

    def set_output(self, driver: str, channel: str, raw: float) -> None:
        b = self.outputs.get((driver, channel))
        if b is None or not math.isfinite(raw):
            return
        with self.lock:
            self.sim.write(b.sim_index, b.gain * raw + b.offset)

    def true_lengths_mm(self) -> dict[str, float]:
        return {p.name: p.length_mm for p in self.sim.plants}

    # -- real-time stepping ---------------------------------------------------------------
    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="emu-physics", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)

    def _run(self) -> None:
        mono = time.monotonic
        last = next_t = mono()
        while not self._stop.is_set():
            next_t += STEP_S
            delay = next_t - mono()
            if delay > 0:
                time.sleep(delay)
            now = mono()
            self.lateness.note(now - next_t)
            if now - next_t > 0.1:
                next_t = now
            if now <= last:
                continue
            with self.lock:
                self.sim.advance(now - last)
            last = now
            self.steps += 1

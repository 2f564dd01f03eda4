"""The simulated rig's sensor readings as the driver publishes them, each through its
injected fault, and the scheduled stall of the loop's process (`drivers/sim.py`; the
failures and their schedule are `pamd.sim.faults`).

A failed sensor's value changes with a new sample only, as a device's: a slow or held
one keeps its last value until the next sample. `stuck` keeps the value while the
stamps advance, `dead` reads 0.0, `silent` stops the stamps, `noisy` adds gaussian
noise of standard deviation `size`, `jump` steps the reading by `size` and stays offset.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import random
import time
from collections.abc import Sequence

from pamd.sim.faults import FAILURES, JUMP_DEFAULT, NOISE_DEFAULT, SimFault
from pamd.sim.plant import MusclePlant

OK, STUCK, DEAD, SILENT, NOISY, JUMP = 0, 1, 2, 3, 4, 5
FAULT_CODES = {"stuck": STUCK, "dead": DEAD, "silent": SILENT, "noisy": NOISY, "jump": JUMP}
SIGNALS: tuple[str, ...] = ("pressure", "force", "length")  # a muscle's inputs, in order
#: what `SimDriver.inject_fault` takes (a `loop` stall comes from the schedule only)
INJECTABLE: tuple[str, ...] = (*SIGNALS, "supply", "valve", "driver", "safety_chain")


def check_fault(signal: str, failure: str) -> None:
    """ValueError unless `signal` can be made to fail as `failure` (`FAILURES`)."""
    if signal not in INJECTABLE:
        raise ValueError(f"unknown signal {signal!r}; use one of {', '.join(INJECTABLE)}")
    failures = FAILURES[signal]
    if failure in failures:
        return
    if signal in SIGNALS:
        raise ValueError(f"unknown sensor fault {failure!r}; use one of {', '.join(failures)}")
    raise ValueError(f"{signal} fault must be {' or '.join(map(repr, failures))}, "
                     f"got {failure!r}")


class FaultSchedule:
    """The options' scripted faults, due in the order of their times."""

    def __init__(self, faults: Sequence[SimFault]) -> None:
        self._faults = sorted(faults, key=lambda f: f.at_s)
        self._next = 0
        self.pending = bool(self._faults)  # read each tick: a plain attribute

    def due(self, elapsed_s: float) -> SimFault | None:
        """The next fault due `elapsed_s` after the driver opened (None: none yet)."""
        if self.pending and self._faults[self._next].at_s <= elapsed_s:
            self._next += 1
            self.pending = self._next < len(self._faults)
            return self._faults[self._next - 1]
        return None


class SensorFaults:
    """The fault of each of the muscles' sensor inputs (input `i` = 3 x muscle + signal),
    and their readings published through it."""

    def __init__(self, n_inputs: int, seed: int) -> None:
        self._n = n_inputs
        self._modes = [OK] * n_inputs
        self._sizes = [0.0] * n_inputs
        self._rng = random.Random(f"pamd.sim.faults:{seed}")
        self.any = False  # a sensor fault stands (else the readings pass as they are)

    def inject(self, i: int, signal: str, failure: str, size: float | None) -> None:
        """Input `i` (of `signal`) fails as `failure` (a key of FAULT_CODES)."""
        self._modes[i] = FAULT_CODES[failure]
        if failure == "noisy":
            self._sizes[i] = NOISE_DEFAULT[signal] if size is None else size
        elif failure == "jump":
            self._sizes[i] = JUMP_DEFAULT[signal] if size is None else size
        self.any = True

    def clear(self) -> None:
        self._modes = [OK] * self._n
        self.any = False

    def publish(self, plants: Sequence[MusclePlant], zero_mm: Sequence[float], now_s: float,
                values: list[float], stamps: list[float], jitters: list[float]) -> None:
        """The plants' readings, each through its fault, into the driver's `values`,
        `stamps` and `jitters` (input 3k + j: muscle k's pressure, force, length; the
        length less `zero_mm[k]`, an incremental encoder's power-up reading). Each is
        stamped with when its device took the sample (its age is 0 for a sensor
        sampled at every step without latency), or on a bursty link with its arrival
        and a jitter (0 otherwise)."""
        for k, plant in enumerate(plants):
            i = 3 * k
            jitters[i] = plant.pressure_jitter_s
            jitters[i + 1] = plant.force_jitter_s
            jitters[i + 2] = plant.length_jitter_s
        if not self.any:
            i = 0
            for k, plant in enumerate(plants):
                values[i] = plant.pressure_read_bar
                values[i + 1] = plant.force_read_n
                values[i + 2] = plant.length_read_mm - zero_mm[k]
                stamps[i] = now_s - plant.pressure_age_s
                stamps[i + 1] = now_s - plant.force_age_s
                stamps[i + 2] = now_s - plant.length_age_s
                i += 3
            return
        modes, sizes = self._modes, self._sizes
        gauss = self._rng.gauss
        i = 0
        for k, plant in enumerate(plants):
            readings = (plant.pressure_read_bar, plant.force_read_n,
                        plant.length_read_mm - zero_mm[k])
            ages = (plant.pressure_age_s, plant.force_age_s, plant.length_age_s)
            for j in range(len(SIGNALS)):
                mode = modes[i]
                stamp = now_s - ages[j]
                # a failed sensor's value changes with a new sample only
                if mode == OK or (mode != SILENT and stamp > stamps[i] + 1e-9):
                    if mode == OK:
                        values[i] = readings[j]
                    elif mode == DEAD:
                        values[i] = 0.0
                    elif mode == NOISY:
                        values[i] = readings[j] + gauss(0.0, sizes[i])
                    elif mode == JUMP:
                        values[i] = readings[j] + sizes[i]
                if mode != SILENT:
                    stamps[i] = stamp
                i += 1


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


# libc through PyDLL: its calls keep the interpreter lock (a stall of the whole process)
_GIL_HOLDING_LIBC = ctypes.PyDLL(ctypes.util.find_library("c") or "libc.so.6")


def stall_process(duration_s: float) -> None:
    """Stop the calling process for `duration_s` (a scheduled `stall`): the calling
    thread (the loop's, in a tick) sleeps in a C call that keeps Python's interpreter
    lock, so no other thread of the process runs either, as when the process gets no
    CPU. Interrupted sleeps go on to the end."""
    end = time.monotonic() + duration_s
    while True:
        left = end - time.monotonic()
        if left <= 0.0:
            return
        ts = _Timespec(int(left), int((left % 1.0) * 1e9))
        _GIL_HOLDING_LIBC.nanosleep(ctypes.byref(ts), None)

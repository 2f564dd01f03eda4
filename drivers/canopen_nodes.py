"""The `canopen-encoder` driver's CiA 406 nodes (`drivers/canopen_encoder.py`): their
configuration (TPDO1 and the heartbeat time by SDO, then NMT start), their heartbeats
and emergencies, the encoder's preset (0x6003, for `home`), and what makes a node
unhealthy. All of it runs on the driver's thread, through the bus the driver owns
(`BusPort`).

A node is unhealthy when it is not configured (retried with backoff), when its
heartbeat is silent longer than `heartbeat_timeout_s` (default three heartbeat times
plus 50 ms: one lost heartbeat is no fault), when it sends no position for
`position_timeout_s`, or while it reports an emergency (EMCY). A node that reboots
(boot-up message) lost its configuration and is configured and started again; one
found stopped or pre-operational is sent NMT start again (at most every 0.5 s).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Sequence
from typing import Protocol

from pamd.drivers.can_frames import (
    NMT_ID,
    NMT_START,
    NMT_STATES,
    OBJ_PRESET,
    SDO_RX_BASE,
    SDO_TX_BASE,
    EncoderNode,
    sdo_download,
    sdo_reply,
    tpdo1_setup,
)
from pamd.drivers.device import Backoff


class BusPort(Protocol):
    """What the nodes need of the driver: its bus, its counters and its error log."""

    @property
    def bus_open(self) -> bool: ...

    def send(self, can_id: int, data: bytes) -> bool: ...

    def receive(self, timeout_s: float) -> object: ...

    def count(self, key: str, n: int = 1) -> None: ...

    def error(self, key: str, message: str, channels: tuple[str, ...] = ()) -> str: ...

    def bad(self, message: str, names: tuple[str, ...]) -> None: ...


class NodeState:
    """Run-time state of one encoder node."""

    def __init__(self, spec_: EncoderNode, index: int) -> None:
        self.spec = spec_
        self.index = index
        self.id = spec_.node_id
        self.needs_config = True
        self.retry_at = 0.0
        self.backoff = Backoff(0.05, 2.0)
        self.started_at = math.inf
        self.last_hb = -math.inf
        self.last_pdo = -math.inf
        self.last_start_cmd = -math.inf
        self.nmt_state = -1
        self.emcy: tuple[int, int] | None = None
        hb = spec_.heartbeat_ms / 1000.0
        self.hb_timeout = spec_.heartbeat_timeout_s or (3.0 * hb + 0.05)

    @property
    def label(self) -> str:
        return f"node {self.id} ({self.spec.name})"

    def problem(self, now: float) -> str | None:
        """Why this started node is unhealthy at `now` (monotonic), or None."""
        since = now - self.started_at
        if self.spec.heartbeat_ms > 0 and now - max(self.last_hb, self.started_at) \
                > self.hb_timeout:
            return (f"{self.label} silent: no heartbeat for "
                    f"{1000 * (now - max(self.last_hb, self.started_at)):.0f} ms")
        timeout = self.spec.position_timeout_s
        if since > timeout and now - max(self.last_pdo, self.started_at) > timeout:
            state = NMT_STATES.get(self.nmt_state, "unknown state")
            return (f"{self.label} sends no position (TPDO1) for "
                    f"{1000 * (now - max(self.last_pdo, self.started_at)):.0f} ms ({state})")
        if self.emcy is not None:
            return f"{self.label} reports emergency 0x{self.emcy[0]:04X}"
        return None


class EncoderNodes:
    """The encoder nodes of one bus, configured and watched from the driver's thread."""

    def __init__(self, encoders: Sequence[EncoderNode], sdo_timeout_s: float,
                 recv_timeout_s: float, lost_after: int, preset_generation: list[int]) -> None:
        self.nodes = [NodeState(e, i) for i, e in enumerate(encoders)]
        self._sdo_timeout_s = sdo_timeout_s
        self._recv_timeout_s = recv_timeout_s
        self._lost_after = lost_after
        self._generation = preset_generation  # the driver's: presets applied per channel
        self._presets: deque[tuple[int, int]] = deque()
        self._sdo_wait: int | None = None
        self._sdo_answer: bytes | None = None

    def take_sdo_answer(self, can_id: int, data: bytes) -> bool:
        """A standard frame: True if it is the SDO answer being waited for (taken)."""
        if can_id != self._sdo_wait:
            return False
        self._sdo_answer = data
        return True

    def queue_preset(self, index: int, counts: int) -> None:
        """Encoder `index` to read `counts` from now on, done by `service`."""
        self._presets.append((index, counts))

    def reconfigure_all(self) -> None:
        """The bus came back (the nodes may have restarted with it): configure them."""
        for n in self.nodes:
            n.needs_config, n.retry_at = True, 0.0

    def service(self, port: BusPort, now: float) -> None:
        """Configure the nodes that are due, then apply the queued presets."""
        for n in self.nodes:
            if n.needs_config and now >= n.retry_at and port.bus_open:
                self._configure(port, n)
        while self._presets and port.bus_open:
            self._preset(port, *self._presets.popleft())

    def problem(self, now: float, config_failures: int, last_error: str) -> str | None:
        """The first node's problem, or None."""
        for n in self.nodes:
            if n.needs_config:
                if n.retry_at > now or config_failures:
                    return f"{n.label} not configured ({last_error})"
                continue
            problem = n.problem(now)
            if problem is not None:
                return problem
        return None

    def heartbeat(self, port: BusPort, n: NodeState, data: bytes) -> None:
        if len(data) < 1:
            port.bad(f"{n.label}: empty heartbeat", (n.spec.name,))
            return
        now = time.monotonic()
        state = data[0] & 0x7F
        n.last_hb = now
        n.nmt_state = state
        port.count("heartbeats")
        if state == 0x00:  # boot-up: the node restarted and lost its configuration
            port.error("node_boots", f"{n.label} restarted (boot-up message)", (n.spec.name,))
            n.needs_config = True
            n.retry_at = now
        elif state in (0x04, 0x7F) and not n.needs_config and now - n.last_start_cmd > 0.5:
            port.error("nmt_restarts", f"{n.label} is {NMT_STATES[state]}; sending NMT start",
                       (n.spec.name,))
            n.last_start_cmd = now
            port.send(NMT_ID, bytes([NMT_START, n.id]))

    def emergency(self, port: BusPort, n: NodeState, data: bytes) -> None:
        if len(data) < 3:
            port.bad(f"{n.label}: EMCY frame of {len(data)} bytes", (n.spec.name,))
            return
        code, register = int.from_bytes(data[:2], "little"), data[2]
        if code == 0:
            n.emcy = None
            port.count("emcy_resets")
        else:
            n.emcy = (code, register)
            port.error("emergencies", f"{n.label} emergency 0x{code:04X} (error register "
                       f"0x{register:02X})", (n.spec.name,))

    def _sdo_write(self, port: BusPort, n: NodeState, index: int, sub: int, value: int,
                   size: int) -> str | None:
        """One expedited download; returns a problem or None. Other frames are handled
        while waiting."""
        self._sdo_wait, self._sdo_answer = SDO_TX_BASE + n.id, None
        answer = None
        timeout_s = self._sdo_timeout_s
        try:
            for attempt in range(self._lost_after):  # a lost reply costs a retry (downloads
                if attempt:  # of a value are idempotent: sending one twice is harmless)
                    port.count("sdo_retries")
                if not port.send(SDO_RX_BASE + n.id, sdo_download(index, sub, value, size)):
                    return f"{n.label}: could not send the SDO request"
                deadline = time.monotonic() + timeout_s
                while self._sdo_answer is None and time.monotonic() < deadline:
                    if not port.bus_open:
                        return f"{n.label}: bus lost during SDO"
                    port.receive(min(self._recv_timeout_s,
                                     max(0.0, deadline - time.monotonic())))
                answer = self._sdo_answer
                if answer is not None:
                    break
                port.count("sdo_timeouts")
        finally:
            self._sdo_wait = None
        if answer is None:
            return (f"{n.label}: no SDO answer to 0x{index:04X}:{sub} within "
                    f"{timeout_s:g} s, {self._lost_after} times in a row")
        ok, why = sdo_reply(answer, index, sub)
        return None if ok else f"{n.label}: {why}"

    def _configure(self, port: BusPort, n: NodeState) -> None:
        now = time.monotonic()
        problem = None
        if n.spec.configure:
            for index, sub, value, size in tpdo1_setup(n.spec):
                problem = self._sdo_write(port, n, index, sub, value, size)
                if problem is not None:
                    break
        if problem is None and port.send(NMT_ID, bytes([NMT_START, n.id])):
            n.needs_config = False
            n.backoff.reset()
            n.started_at = n.last_start_cmd = time.monotonic()
            port.count("nodes_started")
            return
        port.error("config_failures", problem or f"{n.label}: NMT start not sent",
                   (n.spec.name,))
        n.retry_at = now + n.backoff.next()

    def _preset(self, port: BusPort, index: int, counts: int) -> None:
        n = self.nodes[index]
        problem = self._sdo_write(port, n, OBJ_PRESET, 0, counts, 4)
        if problem is None:
            self._generation[index] += 1
            port.count("presets")
        else:
            port.error("preset_failures", f"preset of {n.label} failed: {problem}",
                       (n.spec.name,))

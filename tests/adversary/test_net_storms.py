"""Issue 24's storms, replayed against a real daemon (`pamd run`, real clock, telemetry
and the Foxglove view on their own loopback ports): B7 (garbage frames and subscribes
to unknown channels made the Foxglove server write a stderr line each: 108 MB in
100 s), keepalives under that storm, and waves of 50 Zenoh clients (the io process
grew 94.5 -> 131 MB under 50 clients).

Loopback only; bounded in count and time (a few seconds of storm each); the clients'
memory test compares the io process with itself, wave against wave."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from pamd.client.remote import Client
from tests.adversary.wsraw import OP_BINARY, WS
from tests.net.conftest import RigProc, free_port, wait_listening

RIG = "sim"
STORM_S = 2.0


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RigProc]:
    fox = free_port()
    r = RigProc(tmp_path_factory.mktemp("adv-storm"), RIG,
                args=("--foxglove", f"127.0.0.1:{fox}"))
    r.fox = fox  # type: ignore[attr-defined]
    wait_listening(fox, r.daemon)
    yield r
    r.close()


def io_pid(daemon_pid: int) -> int:
    """The daemon's io process (spawned: `multiprocessing.spawn`'s main)."""
    for tid in Path(f"/proc/{daemon_pid}/task").iterdir():
        for k in (tid / "children").read_text().split():
            if b"spawn_main" in Path(f"/proc/{k}/cmdline").read_bytes():
                return int(k)
    raise AssertionError("no io process")


def rss_kb(pid: int) -> int:
    for ln in Path(f"/proc/{pid}/status").read_text().splitlines():
        if ln.startswith("VmRSS:"):
            return int(ln.split()[1])
    raise AssertionError("no VmRSS")


def test_b7_garbage_frames_grow_the_log_by_a_few_lines_and_keepalives_are_answered(
        rig: RigProc) -> None:
    port = rig.fox  # type: ignore[attr-defined]
    log0 = len(rig.daemon.log())
    stop = threading.Event()
    sent = [0]
    pongs: list[float | None] = []

    def garbage() -> None:
        ws = WS("127.0.0.1", port)
        try:
            while not stop.is_set():
                n = sent[0]
                ws.send(f"garbage {n}")
                ws.send(b"\x99\x00" + n.to_bytes(4, "little"), OP_BINARY)
                ws.send(json.dumps({"op": "subscribe",
                                    "subscriptions": [{"id": n, "channelId": 10**6 + n}]}))
                sent[0] = n + 3
        except OSError:
            pass
        finally:
            ws.close()

    def pinger() -> None:
        ws = WS("127.0.0.1", port)
        try:
            while not stop.is_set():
                pongs.append(ws.ping_s(10.0))
                time.sleep(0.2)
        finally:
            ws.close()

    threads = [threading.Thread(target=garbage), *(threading.Thread(target=pinger)
                                                  for _ in range(3))]
    for t in threads:
        t.start()
    time.sleep(STORM_S)
    stop.set()
    for t in threads:
        t.join(30)
    assert sent[0] >= 300, sent  # a storm, not a trickle
    grew = rig.daemon.log()[log0:]
    fox_lines = [ln for ln in grew.splitlines() if "foxglove" in ln]
    # one line per kind (bad text, bad binary opcode, unknown channel, a dropped
    # connection) per 10 s: never one per frame
    assert len(fox_lines) <= 8, fox_lines
    assert len(grew.encode()) < 4000, grew[-2000:]
    assert pongs and all(p is not None for p in pongs), pongs  # every keepalive answered
    assert rig.status()["ok"]


def test_waves_of_50_zenoh_clients_cost_bounded_memory_that_comes_back(rig: RigProc) -> None:
    pid = io_pid(rig.daemon.proc.pid)
    after: list[int] = []
    peak = before = rss_kb(pid)
    for _wave in range(3):  # the first settles what a first client allocates once
        clients = [Client(connect=rig.endpoint) for _ in range(50)]
        subs = [c.subscribe(f"pamd/{RIG}/state/m1", 16) for c in clients]
        for c in clients:
            assert c.status(RIG, 10.0)["ok"]
        peak = max(peak, rss_kb(pid))
        for s in subs:
            s.undeclare()
        for c in clients:
            c.close()
        after.append(_settled_rss_kb(pid, 3.0))
    # 50 sessions cost some 170 kB each while connected (bounded: at most 100 at once)
    assert peak - before < 40_000, (before, peak)
    # and what they used comes back: no growth wave after wave. Without the heap's trim
    # the two waves after the first left 2.9-4.9 MB (1-2.5 MB a wave); with it Zenoh's
    # and the allocator's bookkeeping leave 0.3-1.7 MB (less wave after wave: under
    # 0.1 MB a wave after twenty; a Zenoh router alone does the same)
    if after[-1] - after[0] >= 2_500:  # a loaded host may run the last trim late: wait
        after[-1] = min(after[-1], _settled_rss_kb(pid, 4.0))  # for two more (no trim: kept)
    assert after[-1] - after[0] < 2_500, (before, after)
    assert rig.status()["ok"]


def _settled_rss_kb(pid: int, for_s: float) -> int:
    """The least resident size over `for_s`: the io loop returns free memory to the OS
    every 2 s (`pamd.iohost.node.trim_heap`)."""
    samples = []
    for _ in range(round(for_s / 0.25)):
        time.sleep(0.25)
        samples.append(rss_kb(pid))
    return min(samples)

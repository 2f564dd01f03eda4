"""Failures stay visible (issue 12, item 4): when the recording's disk fills, `status`
used to answer RUNNING with frozen values and a fresh snapshot age. Now the state is
the loop's (FAULT, by recording.on_failure: safe_state), the failure is in status,
the live values keep coming, and a snapshot the main thread stops refreshing is
marked stale.

The disk fills for real: RLIMIT_FSIZE in the io process (EFBIG on its next write, as
a full disk gives ENOSPC), without root. The daemon runs in this process (so the test
decides when its main thread refreshes the snapshot); the client is its own process
with its own Zenoh session on a free loopback port."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path

from pamd.config.loader import load_config
from pamd.daemon.daemon import Daemon
from pamd.daemon.io_session import RecordingRequest
from pamd.wire.net_spec import TelemetryRequest
from tests.net.conftest import Agent, free_port, rig_config, wait_listening, wait_until


def test_a_full_disk_shows_fault_live_values_and_a_stale_snapshot(
        tmp_path: Path, agents: Callable[..., Agent]) -> None:
    port = free_port()
    cfg = load_config(str(rig_config(tmp_path, port, telemetry={"enabled": True})))
    d = Daemon(cfg, recording=RecordingRequest(dir=str(tmp_path / "rec"),
                                               fsize_limit_bytes=64 * 1024),
               telemetry=TelemetryRequest())
    serving = threading.Event()
    serving.set()
    ended = threading.Event()

    def main_thread() -> None:  # what `pamd run`'s main thread does, while `serving`
        while not ended.is_set():
            if serving.is_set():
                d.service()
            ended.wait(0.02)

    d.start(duration_s=300)
    t = threading.Thread(target=main_thread, daemon=True)
    t.start()
    try:
        wait_listening(port)
        a = agents("--connect", f"tcp/127.0.0.1:{port}")

        def failed() -> dict | None:
            st = a.call("status", rig="sim", timeout=2.0)
            return st if st.get("ok") and (st.get("recording") or {}).get("failure") else None

        st = wait_until(failed, 120, "the recording's failure in status")
        assert "File too large" in st["recording"]["failure"]["reason"], st["recording"]
        st = wait_until(lambda: (s := a.call("status", rig="sim"))["state"] == "FAULT" and s,
                        30, "FAULT in status")
        assert "recording" in st["fault"], st["fault"]
        assert st["stale"] is False and st["stale_reasons"] == []
        tick0 = st["tick"]
        wait_until(lambda: a.call("status", rig="sim")["tick"] > tick0 + 100, 30,
                   "live tick records after the failure")  # not frozen
        serving.clear()  # the main thread stops refreshing the snapshot
        st = wait_until(lambda: (s := a.call("status", rig="sim"))["stale"] and s, 30,
                        "a stale snapshot marked stale")
        assert st["snapshot_age_s"] > 1.0
        assert "has not refreshed the status" in st["stale_reasons"][0], st["stale_reasons"]
        serving.set()
        wait_until(lambda: not a.call("status", rig="sim")["stale"], 30, "fresh again")
    finally:
        ended.set()
        t.join(10)
        d.stop("test finished")
        d.wait(timeout_s=30)
        d.close()
    assert d.result()["recording"]["failure"]["what"] == "write"

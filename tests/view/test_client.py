"""`pamd.connect` against a running daemon (`pamd run`, real clock, its own loopback
port): status, a command and its verdict, a refusal raised with its reason, and the
state stream as numpy batches that follow the command; no daemon: a clear error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pamd

from ..net.conftest import DaemonProc, free_port, rig_config, wait_listening, wait_until


def test_connect_status_command_and_stream(tmp_path: Path) -> None:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    daemon = DaemonProc(tmp_path, ["--config", str(rig_config(tmp_path, port)), "--no-record"])
    try:
        wait_listening(port, daemon)
        with pamd.connect(endpoint=endpoint) as rig:  # the one rig alive
            assert rig.rig == "sim"
            st = wait_until(lambda: (s := rig.status()).get("state") == "IDLE" and s,
                            60.0, "the daemon idle")
            assert "m1" in st["muscles"]
            verdict = rig.command("setpoint", muscle="m1", bar=2.0)
            assert verdict["ok"] is True
            with pytest.raises(pamd.CommandRefused, match="outside"):
                rig.command("setpoint", muscle="m1", bar=99.0)
            refused = rig.command("setpoint", check=False, muscle="m9", bar=1.0)
            assert refused["ok"] is False and "no muscle named 'm9'" in refused["error"]

            def near_two() -> bool:
                got = rig.record(0.5, muscle="m1").get("m1")
                return got is not None and abs(float(got["pressure_bar"][-1]) - 2.0) < 0.1

            wait_until(near_two, 60.0, "the pressure at 2 bar in the stream")
            batches = list(rig.stream("m1", max_batches=5, duration_s=30.0))
        assert len(batches) == 5
        b = batches[-1]
        assert b.muscle == "m1" and len(b) > 0 and b["tick"].dtype == np.int64
        assert set(b.columns) >= {"tick", "t_s", "state", "pressure_bar", "setpoint_bar"}
        ticks = np.concatenate([x["tick"] for x in batches])
        assert (np.diff(ticks) > 0).all()
        assert np.isnan(b["target_length_mm"]).all()  # null (no length target) -> NaN
    finally:
        daemon.stop()


def test_connect_without_a_daemon_says_so() -> None:
    port = free_port()
    with pytest.raises(pamd.NoDaemon, match=f"127.0.0.1:{port}"):
        pamd.connect(endpoint=f"tcp/127.0.0.1:{port}", timeout_s=1.0)

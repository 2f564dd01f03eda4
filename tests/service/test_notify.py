"""The notify protocol as systemd sees it: `pamd run` with a real NOTIFY_SOCKET (a
datagram socket this test binds) sends READY once the loop ticks, WATCHDOG pings
while it ticks on time, STATUS with the supervisor's state, STOPPING on SIGTERM; a
stalled loop gets no pings (and is saved as a latched fault); a rig with a device
missing is still READY, in FAULT, and says why."""

from __future__ import annotations

import json
import os
import signal
import socket
from pathlib import Path

from pamd.daemon.service.notify import Notifier, socket_address
from pamd.emulate.testing import free_port

from .conftest import NotifySocket, sim_dict, wait_until, write_yaml
from .testhooks import STALL_ENV

WATCHDOG_USEC = 400_000  # pings due every 0.2 s


def test_notifier_speaks_the_protocol_and_is_silent_outside_systemd(
        notify: NotifySocket) -> None:
    off = Notifier.from_environ({})
    assert not off.enabled and off.ping_interval_s is None and not off.ready("x")
    n = Notifier.from_environ({"NOTIFY_SOCKET": notify.name, "WATCHDOG_USEC": "3000000"})
    assert n.enabled and n.ping_interval_s == 1.5
    assert n.ready("IDLE: holding\nmeasured") and n.watchdog() and n.stopping("bye")
    assert wait_until(lambda: len(notify.texts()) == 3, 5)
    # one line; the watchdog timeout restated (a restart in place widens it)
    assert notify.texts()[0] == "READY=1\nSTATUS=IDLE: holding measured\nWATCHDOG_USEC=3000000"
    assert notify.texts()[1:] == ["WATCHDOG=1", "STOPPING=1\nSTATUS=bye"]
    # the watchdog is someone else's when WATCHDOG_PID names another process
    other = Notifier.from_environ({"NOTIFY_SOCKET": notify.name, "WATCHDOG_USEC": "3000000",
                                   "WATCHDOG_PID": str(os.getpid() + 1)})
    assert other.enabled and other.ping_interval_s is None
    assert socket_address("@abc") == b"\0abc" and socket_address("/run/x") == "/run/x"
    assert not Notifier.from_environ({"NOTIFY_SOCKET": "relative/path"}).enabled
    gone = Notifier("@pamd-test-nobody-listens")
    assert gone.enabled and not gone.watchdog()  # logged, never raised
    for x in (n, other, gone):
        x.close()


def test_ready_watchdog_status_stopping(tmp_path: Path, notify: NotifySocket,
                                        pamd_run) -> None:
    cfg = write_yaml(tmp_path / "rig.yaml", sim_dict())
    p = pamd_run("--config", cfg, "--state-dir", tmp_path / "state", "--json",
                 env=notify.env(WATCHDOG_USEC))
    assert p.until(lambda: notify.count("WATCHDOG=1") >= 5, 60), (notify.texts(), p.log())
    ready, first_ping = notify.index("READY=1"), notify.index("WATCHDOG=1")
    assert 0 <= ready < first_ping
    assert any(s.startswith("IDLE: sensors read") for s in notify.statuses())
    p.send(signal.SIGTERM)
    assert p.proc.wait(90) == 0, p.log()  # one signal, as systemd sends it
    stopping = notify.index("STOPPING=1")
    assert stopping > first_ping
    assert "SIGTERM received" in notify.texts()[stopping]
    assert json.loads(p.stdout())["final_state"] == "IDLE"


def test_a_stalled_loop_gets_no_pings_and_is_saved_as_a_fault(
        tmp_path: Path, notify: NotifySocket, pamd_run) -> None:
    cfg = write_yaml(tmp_path / "rig.yaml", sim_dict())
    state = tmp_path / "state"
    # the loop's thread sleeps 3 s in tick 375 (1.5 s in at 250 Hz); stall limit 1 s
    p = pamd_run("--config", cfg, "--state-dir", state,
                 env={**notify.env(WATCHDOG_USEC), STALL_ENV: "375:3"})
    assert p.wait_log("TEST HOOK ACTIVE")
    assert p.wait_log("watchdog pings withheld", 60), p.log()
    assert p.wait_log("pings resumed", 60), p.log()

    def gaps_s() -> list[float]:
        pings = notify.ping_times()
        return [b - a for a, b in zip(pings, pings[1:], strict=False)]

    # the log line can come before the resumed ping reaches this socket's reader: wait
    # for that ping (a loop that never withheld its pings has no such gap to wait for)
    assert p.until(lambda: max(gaps_s(), default=0.0) > 1.5, 10), gaps_s()
    pings = notify.ping_times()  # at least 3 s - 1 s; normal gaps are 0.2 s
    gaps = [b - a for a, b in zip(pings, pings[1:], strict=False)]
    before = pings[gaps.index(max(gaps))]
    assert sum(1 for t in pings if t < before) >= 3  # it pinged before the stall ...
    assert p.until(lambda: notify.ping_times()[-1] > before + max(gaps) + 0.5, 30)
    # ... and pings again after it, although the rig is now in FAULT (not a stall)
    assert any(s.startswith("FAULT: loop stalled") for s in notify.statuses())
    fault = json.loads((state / "fault.json").read_text())
    assert fault["state"] == "FAULT" and "loop stalled" in fault["reason"]
    # saved while it hung (a watchdog kill would have found it), then the loop's own
    assert [e for e in fault["earlier"] if "seen by the main thread" in e], fault
    assert "removed" not in p.log()  # only a reset removes it
    assert p.finish() == 0, p.log()


def test_a_missing_device_is_ready_in_fault_and_the_fault_survives_a_restart(
        tmp_path: Path, notify: NotifySocket, pamd_run) -> None:
    state = tmp_path / "state"
    closed = free_port()  # nothing listens there
    d = sim_dict()
    d["drivers"].append({"name": "io", "type": "modbus", "options": {
        "transport": "tcp", "host": "127.0.0.1", "port": closed, "preset": "adam-6024",
        "timeout_s": 0.02, "fault_after_s": 0.3}})  # one lost reply within m1.pressure's 0.05 s
    d["muscles"][0]["signals"]["pressure"] = {"driver": "io", "channel": "ai0"}
    missing = write_yaml(tmp_path / "missing.yaml", d)
    p = pamd_run("--config", missing, "--state-dir", state, "--json",
                 env=notify.env(WATCHDOG_USEC), name="missing")
    assert p.until(lambda: any(s.startswith("FAULT: start-up: no reading from "
                                               "m1.pressure (driver 'io')")
                                  for s in notify.statuses()), 60), (notify.texts(), p.log())
    assert 0 <= notify.index("READY=1") < notify.index("WATCHDOG=1")
    n = notify.count("WATCHDOG=1")
    assert p.until(lambda: notify.count("WATCHDOG=1") >= n + 3, 30)  # FAULT: still pinging
    assert p.finish() == 0, p.log()  # a clean stop; nothing was ever written
    out = json.loads(p.stdout())
    assert out["final_state"] == "FAULT" and "nothing was written" in out["faults"][0]
    saved = json.loads((state / "fault.json").read_text())
    assert saved["state"] == "FAULT" and "m1.pressure" in saved["reason"]

    # Restarted (the device still missing, or a fixed config): it comes back latched.
    notify.messages.clear()
    good = write_yaml(tmp_path / "good.yaml", sim_dict())
    p2 = pamd_run("--config", good, "--state-dir", state, "--json",
                  env=notify.env(WATCHDOG_USEC), name="restarted")
    assert p2.until(lambda: any("kept across a restart" in s for s in notify.statuses()),
                      60), (notify.texts(), p2.log())
    restored = next(s for s in notify.statuses() if "kept across a restart" in s)
    assert restored.startswith("FAULT: start-up: no reading from m1.pressure")
    assert notify.index("READY=1") >= 0
    assert p2.wait_log("sensors read; holding measured pressure")  # read before latching
    assert p2.finish() == 0, p2.log()
    out2 = json.loads(p2.stdout())
    assert out2["final_state"] == "FAULT"
    assert (state / "fault.json").exists()  # still latched: only reset clears it


def test_notify_socket_gone_does_not_stop_the_rig(tmp_path: Path, pamd_run) -> None:
    gone = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    path = tmp_path / "n.sock"
    gone.bind(str(path))
    gone.close()  # the path exists, nobody reads it
    cfg = write_yaml(tmp_path / "rig.yaml", sim_dict())
    p = pamd_run("--config", cfg, "--state-dir", tmp_path / "state", "--duration", "1",
                 env={"NOTIFY_SOCKET": str(path), "WATCHDOG_USEC": str(WATCHDOG_USEC)})
    assert p.proc.wait(60) == 0, p.log()
    assert "cannot notify systemd" in p.log()

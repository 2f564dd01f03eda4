"""SIGHUP with changes that reopen the devices (drivers, rig id, wiring): applied
while IDLE by a restart in place. The daemon waits for IDLE, ends its loop holding
the outputs, finalises its recording, leaves Zenoh, and executes `pamd run` again
in the same process (systemd keeps tracking the PID): RELOADING=1, then READY=1
from the new daemon, which started like every start (read before write)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from mcap.reader import make_reader

from pamd.client.cli.main import build_parser
from pamd.daemon.service.restart import run_argv
from pamd.emulate.testing import free_port

from .conftest import NotifySocket, sim_dict, wait_until, write_yaml
from .test_signals import read_recording


def _zombie_children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[0] == "Z" and int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _pamd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", *args], capture_output=True,
                          text=True, timeout=60, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))


def test_new_driver_config_waits_for_idle_then_restarts_in_place(
        tmp_path: Path, notify: NotifySocket, pamd_run) -> None:
    port = free_port()
    where = f"tcp/127.0.0.1:{port}"
    telemetry = {"enabled": True, "listen": where}
    first = sim_dict(telemetry=telemetry)
    cfg = write_yaml(tmp_path / "rig.yaml", first)
    rec = tmp_path / "rec"
    p = pamd_run("--config", cfg, "--state-dir", tmp_path / "state", "--record", rec,
                 "--json", env=notify.env(400_000))
    assert p.until(lambda: notify.index("READY=1") >= 0, 60), p.log()
    r = _pamd("cmd", "--connect", where, "--rig", "sim", "profile", "--kind", "sine",
              "--min-bar", "0.5", "--max-bar", "2", "--freq-hz", "0.2")
    assert r.returncode == 0, r.stdout + r.stderr

    drv = first["drivers"][0]
    second = sim_dict(telemetry=telemetry, rig_id="simb", drivers=[
        dict(drv, options=dict(drv["options"], seed=2))])
    write_yaml(cfg, second)
    p.send(signal.SIGHUP)
    assert p.wait_log("once the rig is at rest (it is RUNNING", 30), p.log()
    assert "rig_id 'sim' -> 'simb'" in p.log() and "drivers[0].options.seed" in p.log()
    assert p.until(lambda: any("restart in place for a config reload waiting for the rig "
                               "to rest" in s for s in notify.statuses()), 30)
    assert "restarting in place" not in p.log()  # not while the profile runs

    r = _pamd("cmd", "--connect", where, "--rig", "sim", "stop")
    assert r.returncode == 0, r.stdout + r.stderr
    assert p.wait_log(f"restarting in place (pid {p.proc.pid})", 60), p.log()
    ready_before = notify.index("RELOADING=1")
    # the new daemon, in the same process, under its new rig id
    assert p.until(lambda: p.log().count("sensors read") >= 2, 60), p.log()
    assert p.until(lambda: notify.count("READY=1") >= 3, 60), (notify.texts(), p.log())
    assert p.proc.poll() is None
    texts = notify.texts()
    widened = next(i for i, m in enumerate(texts) if "WATCHDOG_USEC=60000000" in m)
    ready_again = max(i for i, m in enumerate(texts) if "READY=1" in m.split("\n"))
    assert ready_before < widened < ready_again
    assert "WATCHDOG_USEC=400000" in texts[ready_again]  # set back
    # the restarted daemon pings through its own start, before its READY=1 (issue 38)
    assert "WATCHDOG=1" in texts[widened + 1:ready_again], texts[widened:ready_again + 1]
    assert "STOPPING=1" not in "\n".join(texts)  # a reload, not a stop
    assert _zombie_children(p.proc.pid) == []  # the old image's helpers were reaped
    st = None

    def status() -> bool:
        nonlocal st
        r = _pamd("status", "--connect", where, "--rig", "simb", "--json", "--timeout", "5")
        st = r.stdout
        return r.returncode == 0

    assert wait_until(status, 60, step_s=0.5), (st, p.log())
    assert json.loads(st)["state"] == "IDLE"

    p.send(signal.SIGTERM)
    assert p.proc.wait(90) == 0, p.log()  # one signal, as systemd sends it
    out = json.loads(p.stdout())  # only the new daemon prints a summary with --json
    assert out["rig_id"] == "simb" and out["final_state"] == "IDLE" and out["faults"] == []
    files = sorted(rec.glob("*.mcap"))
    assert len(files) == 2, files
    for path in files:  # both finalised: the summary section and footer are there
        with open(path, "rb") as fh:
            reader = make_reader(fh)
            assert reader.get_summary() is not None
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        rig = "sim" if path.name.split("_")[1] == "sim" else "simb"
        assert meta["pamd"]["rig_id"] == rig
        assert meta["pamd"]["pid"] == str(p.proc.pid)
    assert {f.name.split("_")[1] for f in files} == {"sim", "simb"}
    first_meta = [f for f in files if f.name.split("_")[1] == "sim"][0]
    with open(first_meta, "rb") as fh:
        meta = {m.name: dict(m.metadata) for m in make_reader(fh).iter_metadata()}
    reason = meta["pamd.summary"]["stop_reason"]
    assert reason.startswith("config reload: ") and "rig_id 'sim' -> 'simb'" in reason
    assert meta["pamd.summary"]["final_state"] == "IDLE"
    # the restart waited for rest: the stop's ramp ran to the safe pressure before the
    # loop handed over (issue 38: it ended 22 ms into the ramp, the command at 2.288 bar)
    _summary, _meta, states = read_recording(first_meta)
    assert max(st.setpoint_bar for st in states) > 0.5  # the profile had the pressure up
    last = states[-1]
    assert abs(last.setpoint_bar - last.safe_pressure_bar) < 1e-9, last
    assert abs(last.valve_cmd_bar - last.safe_pressure_bar) < 0.05, last


def test_a_stop_during_the_restart_reaches_the_new_process(tmp_path: Path) -> None:
    """The exec keeps the PID; a stop signal that came while the old daemon closed is
    pending for the new one and is delivered once it has its handlers."""
    child = textwrap.dedent("""
        import os, signal
        got = []
        signal.signal(signal.SIGTERM, lambda s, f: got.append(s))
        from pamd.daemon.service.restart import unblock_signals
        unblock_signals()
        print("child", os.getpid(), got, flush=True)
    """)
    parent = textwrap.dedent(f"""
        import os, sys
        from pamd.daemon.service.restart import restart_in_place
        print("parent", os.getpid(), flush=True)
        restart_in_place([sys.executable, "-c", {child!r}], "test", stop_received=True)
    """)
    r = subprocess.run([sys.executable, "-c", parent], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    (p_line, c_line) = r.stdout.split("\n")[:2]
    assert p_line.split()[1] == c_line.split()[1]  # the same process
    assert c_line.endswith(f"[{int(signal.SIGTERM)}]")  # the stop was not lost


def test_the_restarted_daemon_keeps_its_standing_options_only() -> None:
    args = build_parser().parse_args([
        "run", "--config", "/etc/pamd/pamd.yaml", "--state-dir", "/var/lib/pamd",
        "--profile", "sine", "--cycles", "3", "--mode", "position", "--no-feedforward",
        "--duration", "100", "--no-telemetry", "--record", "/srv/rec", "--json",
        "--load-kg", "m1=45", "--load-kg", "m2=12.5"])
    argv = run_argv(args, remaining_s=40.5)
    assert argv[:4] == [sys.executable, "-m", "pamd", "run"]
    assert argv[4:] == ["--config", "/etc/pamd/pamd.yaml", "--json", "--load-kg",
                        "m1=45.0,m2=12.5", "--state-dir", "/var/lib/pamd", "--record",
                        "/srv/rec", "--no-telemetry", "--duration", "40.5"]
    again = build_parser().parse_args(argv[3:]).load_kg  # read back: the same loads
    assert [pair for g in again for pair in g] == [pair for g in args.load_kg for pair in g]

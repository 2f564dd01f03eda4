"""Offline datum commands (`pamd home`, `pamd tare`): open the configured rig
without a daemon or Zenoh, read every sensor, apply one command through the same
loop-side handler a running daemon uses (so the same refusals apply), save the
calibration file, and leave the outputs as they were.

Start-up is the daemon's: nothing is written before every sensor is read; inside
its limits the rig holds its measured pressure (nothing moves); outside them it
ramps to its safe pressure first, and the datum is taken once it rests. The
run then ends holding its outputs (a VPPM keeps its pressure), not ramping to the
safe state, unless it is latched in FAULT or ESTOP.
"""

from __future__ import annotations

import argparse
import json
import time

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.loop.safety.datums import AT_REST_MM_S
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused, DriverError
from pamd.wire.tick import State

#: How long the rig may take to read its sensors and come to rest.
SETTLE_TIMEOUT_S = 10.0


def _at_rest(d: Daemon) -> bool:
    ctrl = d.ctrl
    return all(abs(m.velocity_mm_s) < AT_REST_MM_S and (
        not m.in_safe_ramp or abs(m.setpoint_bar - m.safe_pressure_bar) < 1e-6)
        for m in ctrl.muscles)


def add_state_args(p: argparse.ArgumentParser) -> None:
    """--state-dir and --json, as every offline datum command takes them."""
    p.add_argument("--state-dir", metavar="DIR", help="the state directory whose "
                   "calibration.yaml keeps the datums (the service's: /var/lib/pamd; "
                   "default: as `pamd run` keeps it, see state_dir)")
    p.add_argument("--json", action="store_true", help="print the verdict as JSON")


def apply_offline(config: str | None, verb: str, payload: JsonObject,
                  state_dir: str | None = None) -> JsonObject:
    """Open the rig, apply `verb` once it rests, save the datums (in the state
    directory, or the config's `calibration_file`); the verdict. CommandRefused when
    refused (nothing saved), DriverError if the rig never read."""
    cfg = load_config(config)
    d = Daemon(cfg, state_dir=state_dir)
    d.start()
    try:
        st = d.wait_for_state((State.IDLE, State.FAULT, State.ESTOP), SETTLE_TIMEOUT_S)
        if st == State.STARTING:
            raise DriverError(f"the rig did not start: {d.ctrl.supervisor.reason}")
        if st == State.IDLE:
            deadline = time.monotonic() + SETTLE_TIMEOUT_S
            while not _at_rest(d) and time.monotonic() < deadline:
                d.wait_for_state((State.FAULT,), 0.05)
        verdict = d.command(verb, payload)
        state = d.ctrl.supervisor.state
        if state == State.IDLE:
            d.loop.request_handover(f"offline {verb} done")  # outputs held, nothing moves
        else:
            d.stop(f"offline {verb} done")
        d.wait(timeout_s=30)
    finally:
        d.stop(f"offline {verb} finished")
        d.wait(timeout_s=30)
        d.close()
    if not verdict.get("ok"):
        raise CommandRefused(verdict.get("error", f"{verb} refused"))
    verdict["calibration_file"] = d.calibration_path or "none (kept for that run only)"
    return verdict


def print_verdict(verdict: JsonObject, as_json: bool) -> None:
    if as_json:
        print(json.dumps(verdict, sort_keys=True))
        return
    for k, v in verdict.items():
        if k != "ok":
            print(f"  {k}: {v}")

"""The status snapshot, built here, in one place, by the daemon's main thread a few
times a second (never by the loop's thread, never per tick); its fields are declared
in `pamd.net.status`. The io process answers it from the board."""

from __future__ import annotations

import getpass
import os
import time
from collections.abc import Callable
from typing import Any

from pamd.experiment.sequencer import running_plan
from pamd.net.status import jsonsafe
from pamd.verbs.table import VERBS
from pamd.version import __version__


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return f"uid {os.getuid()}"


class StatusBuilder:
    """Builds the snapshot from a running `Daemon` (its main thread)."""

    def __init__(self, daemon: Any,
                 collection: Callable[[], dict[str, Any] | None] = lambda: None) -> None:
        """`collection`: the collection started over the network that runs, if any."""
        self.d = daemon
        self.t0 = time.monotonic()
        self.collection = collection
        self.user = _user()  # whose daemon it is (a status says so)

    def build(self, now: float) -> dict[str, Any]:
        d = self.d
        ctrl, cfg = d.ctrl, d.cfg
        st = ctrl.status()
        deadman = getattr(ctrl, "deadman", {})
        for m in ctrl.muscles:
            ms = st["muscles"].get(m.name)
            if ms is None:
                continue
            ref = m.reference
            ms["references"] = {
                "length_referenced": ref.length_referenced, "homed_at": ref.homed_at,
                "tared_at": ref.tared_at, "length_offset_mm": ref.length_offset_mm,
                "force_offset_n": ref.force_offset_n}
            ff = m.length_control.ff
            ms["model"] = ff.describe() if ff is not None else None
            ms["adapt"] = m.adaptation.describe()  # online adaptation (pamd.control.adapt)
            dm = deadman.get(m.name)
            ms["deadman_left_s"] = None if dm is None else max(0.0, dm[0] - ctrl.now)
        seq = running_plan(ctrl)
        experiment = None
        if seq is not None:
            experiment = {"plan": seq.plan.name, "step": seq.index, "phase": seq.phase,
                          "outcome": seq.outcome or None,
                          "awaiting_operator": seq.awaiting_operator or None,
                          "collection": self.collection()}
        io = getattr(d, "io", None)
        rec = None
        if io is not None and getattr(io, "recording", True):
            rec = {"files": io.link.files(), "failure": io.failure}
        st.update(
            rig_id=cfg.rig.rig_id, faults=list(ctrl.supervisor.faults),
            experiment=experiment, config_sha256=cfg.sha256,
            config_path=os.path.abspath(cfg.path), clock="virtual" if d.loop.virtual else "real",
            rate_hz=cfg.rig.loop.rate_hz, verbs=sorted(VERBS.names), recording=rec,
            stopping=d.loop.stop_requested, pamd_version=__version__, pid=os.getpid(),
            user=self.user, t_wall_s=time.time(), uptime_s=now - self.t0)
        return jsonsafe(st)

"""An io process attached to a daemon: builds the shared block and the spec, puts
the ring sink downstream of the summary sink and the ring mailbox beside the local
one, and decides what a lost io process or a failed write means (by config: fault to
the safe state, or keep controlling without recording; either way it says so)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

from pamd.io.link import IoLink, MultiMailbox, RingMailbox, RingSink
from pamd.io.meta import build_record_spec
from pamd.io.spec import IoSpec
from pamd.ipc.ring import BlockLayout, pow2_at_least


@dataclass(frozen=True)
class RecordingRequest:
    """What the caller (CLI, tests) asks of the io process for one run."""

    dir: str | None = None  # overrides recording.dir of the config
    enabled: bool = True  # False: no recording even if the config names a dir
    run_name: str | None = None
    model_path: str | None = None  # the ANFIS model in use, attached to the file
    profile: dict[str, Any] | None = None  # the profile or experiment step, as metadata
    script: tuple[tuple[int, str, dict], ...] = ()  # io-side commands (tick, verb, payload)
    fsize_limit_bytes: int | None = None  # tests: make writes fail for real
    segments: tuple[dict[str, Any], ...] = ()  # experiment steps: one file each


class IoSession:
    def __init__(self, daemon: Any, req: RecordingRequest, record_dir: str) -> None:
        self.daemon = daemon
        cfg = daemon.cfg
        self.rc = cfg.rig.recording
        loop = daemon.loop
        self.virtual = loop.virtual
        self.failure: dict[str, Any] | None = None
        clock0 = 0.0 if self.virtual else time.monotonic()
        wall0 = time.time_ns()
        rate = cfg.rig.loop.rate_hz
        layout = BlockLayout(record_bytes=8 * daemon.layout.size,
                             tick_slots=pow2_at_least(max(64, int(self.rc.ring_s * rate))))
        rspec = build_record_spec(
            cfg, daemon.calibration, record_dir=record_dir, note=daemon.note,
            run_name=req.run_name, model_path=req.model_path, profile=req.profile,
            virtual=self.virtual, wall0_ns=wall0, fsize_limit_bytes=req.fsize_limit_bytes,
            steps=req.segments)

        def make_spec(shm_name: str) -> IoSpec:
            return IoSpec(shm_name=shm_name, layout=layout, rig_id=cfg.rig.rig_id,
                          muscles=tuple(daemon.layout.muscles), rate_hz=rate,
                          virtual=self.virtual, wall0_ns=wall0, clock0_s=clock0,
                          parent_pid=os.getpid(), record=rspec, script=tuple(req.script))

        self.link = IoLink.create(make_spec, layout)
        ctrl = daemon.ctrl
        self.sink = RingSink(self.link, self.virtual, lambda: ctrl.t_start, self._failed,
                             loop.notices.append)
        self.mailbox = RingMailbox(self.link, self.sink, lambda: ctrl.now)
        daemon.summary.downstream.append(self.sink)
        loop.mailbox = MultiMailbox(daemon.mailbox, self.mailbox)

    @classmethod
    def attach(cls, daemon: Any, req: RecordingRequest | None) -> IoSession | None:
        req = req or RecordingRequest()
        record_dir = req.dir or daemon.cfg.rig.recording.dir
        if not req.enabled or not record_dir:
            return None
        return cls(daemon, req, record_dir)

    def start(self) -> None:
        self.link.start()

    def _failed(self, what: str, reason: str) -> None:
        """In the loop's thread: the io process died or could not write."""
        policy = self.rc.on_io_death if what == "death" else self.rc.on_failure
        key = "on_io_death" if what == "death" else "on_failure"
        ctrl = self.daemon.ctrl
        if policy == "safe_state":
            msg = f"recording stopped: {reason}; going to the safe state (recording.{key})"
        else:
            msg = (f"recording stopped: {reason}; control continues WITHOUT recording "
                   f"(recording.{key}: continue)")
        self.failure = {"what": what, "reason": reason, "policy": policy,
                        "tick": ctrl.tick_no}
        self.daemon.loop.notices.append(msg)
        self.daemon.summary.event(ctrl.now, "recording", dict(self.failure, message=msg))
        if policy == "safe_state":
            ctrl.supervisor.fault(ctrl.now, f"recording: {reason}")

    def close(self, summary: dict[str, Any]) -> None:
        if self.link.closed:
            return
        self.sink.finish(summary)
        self.link.close()

    def result(self) -> dict[str, Any]:
        st = self.link.status()
        st["lost_records"] = self.sink.lost_records
        st["lost_events"] = max(self.sink.lost_events, st.get("lost_events") or 0)
        st["failure"] = self.failure
        return st

"""What each recording states about itself: metadata records and attachments built
from the daemon's config, calibration, model and the operator's note."""

from __future__ import annotations

import dataclasses
import json
import os
import platform
import socket
import sys
import time

from pamd.config.loader import LoadedConfig
from pamd.loop.devices.datum_file import Calibration
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.record.record_spec import RecordSpec
from pamd.wire.version import __version__


def _s(v: object) -> str:
    return v if isinstance(v, str) else json.dumps(v, default=str)


def build_record_spec(cfg: LoadedConfig, calibration: Calibration, *, record_dir: str,
                      note: str = "", run_name: str | None = None,
                      model_path: str | None = None, profile: JsonObject | None = None,
                      virtual: bool, wall0_ns: int,
                      fsize_limit_bytes: int | None = None, max_mb: float | None = None,
                      steps: tuple[JsonObject, ...] = ()) -> RecordSpec:
    rc = cfg.rig.recording
    started = time.strftime("%Y%m%d-%H%M%S", time.localtime(wall0_ns / 1e9))
    rig = cfg.rig
    meta: dict[str, dict[str, str]] = {
        "pamd": {
            "pamd_version": __version__, "host": socket.gethostname(),
            "python": sys.version.split()[0], "platform": platform.platform(),
            "rig_id": rig.rig_id, "run_name": run_name or rc.run_name,
            "started_at": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(wall0_ns / 1e9)),
            "clock": "virtual" if virtual else rig.loop.clock, "rate_hz": _s(rig.loop.rate_hz),
            "time_base": ("virtual: run start (wall clock) + tick x period" if virtual
                          else "wall clock of each tick's sample clock edge (on the monotonic "
                          "clock)" if rig.loop.clock == "daq"
                          else "wall clock of each tick's scheduled time"),
            "muscles": ",".join(m.name for m in rig.muscles), "note": note,
            "config_path": os.path.abspath(cfg.path), "config_sha256": cfg.sha256,
            "pid": str(os.getpid()),
        },
        "pamd.config": {
            "resolved": json.dumps(dataclasses.asdict(rig), default=str),
            "path": os.path.abspath(cfg.path), "sha256": cfg.sha256,
        },
        "pamd.calibration": {
            name: json.dumps(dataclasses.asdict(ref))
            for name, ref in sorted(calibration.muscles.items())
        } | {"file": cfg.calibration_path or ""},
        "pamd.loads": {m.name: _s(m.load_kg) for m in rig.muscles},
    }
    atts: list[tuple[str, str, bytes]] = [
        (os.path.basename(cfg.path) or "config.yaml", "application/yaml", cfg.text.encode())]
    if cfg.calibration_path and os.path.exists(cfg.calibration_path):
        with open(cfg.calibration_path, "rb") as fh:
            atts.append((os.path.basename(cfg.calibration_path), "application/yaml", fh.read()))
    if profile:
        meta["pamd.profile"] = {k: _s(v) for k, v in profile.items()}
    if model_path:
        with open(model_path, "rb") as fh:
            blob = fh.read()
        meta["pamd.model"] = {"path": os.path.abspath(model_path), "bytes": str(len(blob))}
        atts.append((f"model/{os.path.basename(model_path)}", "application/octet-stream", blob))
    return RecordSpec(
        dir=record_dir, run_name=run_name or rc.run_name, rotate_mb=rc.rotate_mb,
        rotate_s=rc.rotate_s, chunk_kb=rc.chunk_kb, flush_s=rc.flush_s,
        compression=rc.compression, started_at=started, metadata=meta,
        attachments=tuple(atts), fsize_limit_bytes=fsize_limit_bytes, steps=steps,
        max_mb=max_mb)

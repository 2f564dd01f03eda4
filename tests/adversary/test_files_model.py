"""Adversary (issue 24, B5 and "a verdict that comes too late"): a maximal model file
(7 MB, 180,000 rules, just under the 8 MiB cap) and a plan file at its 1 MiB cap,
named in remote commands to a running daemon (its own loopback port).
Each is answered within the client's default command timeout (5 s) with a refusal
that names the file, while the loop goes on; a model at the cap's byte is refused
unread. How late the loop wakes meanwhile is measured by
`bench/files_model_load.py`, not asserted here."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pamd.client.remote import Client
from pamd.emulate.testing import free_port
from pamd.models.anfis.model import AnfisModel
from pamd.models.anfis.serialize import to_dict
from pamd.models.contract import Variable

REPO = Path(__file__).resolve().parents[2]


def anfis(n_mfs: tuple[int, int]) -> AnfisModel:
    ins = [Variable("force_n", "N", 0.0, 600.0), Variable("length_mm", "mm", 140.0, 205.0)]
    cons = np.zeros((int(np.prod(n_mfs)), 3))
    cons[:, 2] = 3.0
    return AnfisModel(ins, Variable("pressure_bar", "bar", 0.0, 6.0), mf_type="gaussian",
                      scaling="minmax", scale_offset=[0.0, 140.0], scale_span=[600.0, 65.0],
                      centres=[np.linspace(0.0, 1.0, n) for n in n_mfs],
                      widths=[np.full(n, 0.5 / n) for n in n_mfs], consequents=cons)


class Daemon:
    def __init__(self, tmp: Path) -> None:
        self.port = free_port()
        data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
        # the virtual clock: no stall fault on a busy machine, and the commands' path
        # (io process, main thread, child, loop) is the same
        data["loop"].update(clock="virtual", rate_hz=500, realtime={"enabled": False})
        data["telemetry"] = {"enabled": True, "listen": f"tcp/127.0.0.1:{self.port}",
                             "models_dir": "models",
                             "plans_dir": "plans"}  # the default command_timeout_s: 5 s
        (tmp / "models").mkdir()
        (tmp / "plans").mkdir()
        cfg = tmp / "rig.yaml"
        cfg.write_text(yaml.safe_dump(data))
        self.tmp = tmp
        self.log = open(tmp / "daemon.log", "w")  # noqa: SIM115
        self.proc = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config",
                                      str(cfg), "--no-record"], cwd=tmp,
                                     stdout=subprocess.DEVNULL, stderr=self.log)
        deadline = time.monotonic() + 90
        while True:  # the io process listens once it has started
            assert self.proc.poll() is None, (tmp / "daemon.log").read_text()[-3000:]
            assert time.monotonic() < deadline, "nothing listens"
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    break
            time.sleep(0.1)
        self.client = Client(connect=f"tcp/127.0.0.1:{self.port}")
        while time.monotonic() < deadline:
            assert self.proc.poll() is None, (tmp / "daemon.log").read_text()[-3000:]
            try:
                if self.client.status("sim", 1.0).get("state") not in (None, "STARTING"):
                    return
            except Exception:
                pass
            time.sleep(0.2)
        raise AssertionError("the daemon does not answer")

    def cmd(self, verb: str, payload: dict[str, Any]) -> tuple[dict[str, Any], float]:
        t0 = time.monotonic()
        v = self.client.command("sim", verb, payload, timeout_s=30.0)
        return v, time.monotonic() - t0

    def close(self) -> None:
        self.client.close()
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self.log.close()


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    d = Daemon(tmp_path_factory.mktemp("files-model"))
    yield d
    d.close()


def test_a_maximal_model_named_remotely_is_refused_within_the_timeout(daemon: Daemon
                                                                      ) -> None:
    path = daemon.tmp / "models" / "maximal.json"
    path.write_text(json.dumps(to_dict(anfis((400, 450))), separators=(",", ":")))
    assert 6e6 < path.stat().st_size <= 8 * 1024 * 1024
    for _ in range(2):
        v, _took = daemon.cmd("model", {"muscle": "m1", "file": "maximal.json"})
        assert not v["ok"] and "maximal.json" in v["error"], v
        # either it was read and found too large for the tick, or not read within 3 s
        assert ("180000 rules is too many for the tick" in v["error"]
                or "not read within 3 s" in v["error"]), v
        assert "no verdict" not in v["error"], v  # answered by the daemon, in time
    assert daemon.proc.poll() is None
    st = daemon.client.status("sim", 2.0)
    assert st["ok"] and not st["muscles"]["m1"]["model"], st  # nothing swapped in


def test_a_model_one_byte_over_the_cap_is_refused_unread(daemon: Daemon) -> None:
    (daemon.tmp / "models" / "huge.json").write_bytes(b" " * (8 * 1024 * 1024 + 1))
    v, _ = daemon.cmd("model", {"muscle": "m1", "file": "huge.json"})
    assert not v["ok"] and "above the limit of 8388608 bytes" in v["error"], v


def test_a_plan_at_its_cap_is_answered_within_the_timeout(daemon: Daemon) -> None:
    """1 MiB of steps: parsed (YAML, in pure Python: seconds) in the child, not the
    daemon; the verdict, whichever it is, comes from the daemon within 5 s."""
    steps = "".join(f"  - {{name: s{i}, hold_s: 1}}\n" for i in range(40000))
    text = "name: big\nmuscle: m1\nsteps:\n" + steps
    text = text[: (1 << 20) - 200]
    text = text[: text.rfind("\n") + 1]
    (daemon.tmp / "plans" / "big.yaml").write_text(text)
    assert os.path.getsize(daemon.tmp / "plans" / "big.yaml") <= 1 << 20
    v, _took = daemon.cmd("collect", {"plan_file": "big.yaml"})
    assert not v["ok"] and "no verdict" not in v["error"], v
    assert "plan refused" in v["error"] or "does not record" in v["error"], v
    assert daemon.proc.poll() is None

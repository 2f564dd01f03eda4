"""Pseudo-terminal pairs made by socat, for serial links between two processes
(Modbus RTU, python-can's `serial` interface, line-protocol devices).

`PtyPair(host_path)` links `host_path` (the daemon opens it) to `host_path + ".dev"`
(the emulated device opens it). socat removes the links when it ends.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time

DEVICE_SUFFIX = ".dev"


def socat_available() -> bool:
    return shutil.which("socat") is not None


class PtyPair:
    """A socat-made pty pair: `host` for the daemon, `device` for the emulator."""

    def __init__(self, host: str, device: str | None = None, timeout_s: float = 5.0) -> None:
        if not socat_available():
            raise RuntimeError("socat is not installed (apt-get install socat); it makes the "
                               "pty pairs that carry serial links between processes")
        self.host = host
        self.device = device or host + DEVICE_SUFFIX
        os.makedirs(os.path.dirname(os.path.abspath(host)) or ".", exist_ok=True)
        for p in (self.host, self.device):
            if os.path.islink(p):
                os.unlink(p)
        self.proc = subprocess.Popen(
            ["socat", f"pty,raw,echo=0,link={self.host}",
             f"pty,raw,echo=0,link={self.device}"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            # its own session: a Ctrl-C at the terminal is for pamd, which closes the
            # links after the devices on them (socat gone first pulls the pty from
            # under a reading thread)
            start_new_session=True)
        deadline = time.monotonic() + timeout_s
        while not (os.path.exists(self.host) and os.path.exists(self.device)):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.close()
                raise RuntimeError(f"socat did not make the pty pair {self.host} <-> "
                                   f"{self.device}")
            time.sleep(0.01)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(3.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def __enter__(self) -> PtyPair:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

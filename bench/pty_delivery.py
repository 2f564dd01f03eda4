"""How late a pty delivers bytes, against a socket, beside CPU hogs: the wire the
emulated rig's Modbus RTU and CAN links used (socat pty pairs, `pamd.emulate.ptys`;
since issue 23 they run over loopback sockets by default, RTU frames over TCP and
socketcand, and ptys are an option: this is why).

A writer thread puts its clock into the link every millisecond, a reader thread of
the same process takes it out; both run at SCHED_FIFO (priority 2, as an emulator and
a daemon's driver thread would, when allowed), so neither is what waits. Beside two
CPU hogs at normal priority, on the shared 2-core machine of 2026-11-26 (load average
16-28 from other engineers' work), the pty delivered up to 91 ms late (86 times later
than 20 ms in 25 s; a second run of 15 s: 32 ms, 19 times), the socket within 3.1 ms
(1.3 ms):
a pty's bytes are handed to its reader by kernel work that runs at normal priority,
which the hogs starve. So a real-time daemon reading a pty-carried link (the emulated
rig's RTU and CAN; a USB-RS485 adapter goes through the same tty layer) sees gaps its
own priority cannot prevent (bench/shared_machine.py).

usage: python bench/pty_delivery.py [--seconds 25] [--hogs 2]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import socket
import struct
import subprocess
import sys
import threading
import time
import tty

PRIORITY = 2
LATE_S = 0.02
HOG = "while True: pass"


def normal_priority() -> None:
    """In a hog before it runs: SCHED_OTHER at nice 0 (this script runs SCHED_FIFO)."""
    with contextlib.suppress(OSError):  # not the real-time policy a parent may have
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    with contextlib.suppress(OSError):
        os.setpriority(os.PRIO_PROCESS, 0, 0)


def measure(kind: str, seconds: float) -> tuple[float, int, int]:
    """(worst delivery s, deliveries later than LATE_S, samples) over a `kind` link."""
    closers: list[object] = []
    if kind == "pty":
        wfd, rfd = os.openpty()
        tty.setraw(rfd)
    else:
        a, b = socket.socketpair()
        closers = [a, b]
        wfd, rfd = a.fileno(), b.fileno()
    worst, late, n = 0.0, 0, 0
    stop = threading.Event()

    def reader() -> None:
        nonlocal worst, late, n
        buf = b""
        while not stop.is_set():
            buf += os.read(rfd, 4096)
            now = time.monotonic()
            while len(buf) >= 8:
                sent = struct.unpack("d", buf[:8])[0]
                buf = buf[8:]
                worst = max(worst, now - sent)
                late += now - sent > LATE_S
                n += 1

    th = threading.Thread(target=reader, daemon=True)
    th.start()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        os.write(wfd, struct.pack("d", time.monotonic()))
        time.sleep(0.001)
    stop.set()
    os.write(wfd, struct.pack("d", time.monotonic()))  # wake the reader
    th.join(2.0)
    if kind == "pty":
        os.close(wfd)
        os.close(rfd)
    for c in closers:
        c.close()  # type: ignore[attr-defined]
    return worst, late, n


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=25.0, help="per link (25)")
    p.add_argument("--hogs", type=int, default=2, help="CPU hogs at normal priority (2)")
    args = p.parse_args()
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
        where = f"SCHED_FIFO {PRIORITY}"
    except OSError as exc:
        where = f"normal priority (SCHED_FIFO refused: {exc})"
    hogs = [subprocess.Popen([sys.executable, "-c", HOG], preexec_fn=normal_priority)
            for _ in range(args.hogs)]
    try:
        print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}, writer and "
              f"reader at {where}, {args.hogs} CPU hogs at normal priority")
        for kind in ("pty", "socket"):
            worst, late, n = measure(kind, args.seconds)
            print(f"  {kind:6s}: worst delivery {1000 * worst:6.1f} ms, {late} of {n} later "
                  f"than {1000 * LATE_S:g} ms", flush=True)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    return 0


if __name__ == "__main__":
    sys.exit(main())

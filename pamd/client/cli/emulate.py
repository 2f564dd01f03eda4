"""`pamd emulate`: serve a rig config's field devices from simulated muscles through
the real protocols (Modbus TCP, Modbus RTU frames over TCP and CAN through a
socketcand server, all on loopback; RTU and CAN over socat pty pairs as an option), so
`pamd run --config` the same file drives an emulated rig end to end."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from types import FrameType

from pamd.config import load_config
from pamd.config.loader import LoadedConfig
from pamd.daemon.service.riglock import RunLocks
from pamd.drivers import load_driver_class
from pamd.wire.errors import DriverError


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "emulate", help="serve an emulated rig through real protocols",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Play the devices a rig config expects, with the simulated DMSP-20 "
        "muscles behind them, on loopback: a Modbus TCP module, a Modbus RTU device "
        "behind an RS-485 device server (transport rtu-tcp, or rtu on a socket:// URL), "
        "CiA 406 encoders on a CAN bus served by a socketcand server (interface "
        "socketcand), and NI-DAQmx devices (nidaqmx drivers: an NI gRPC Device Server on "
        "the driver's `server`, a USB-6211's channels on its sample clock, which NI's own "
        "nidaqmx library drives). Over ptys instead (socat needed): Modbus RTU on a "
        "serial_port path (the daemon's end; <port>.dev the emulator's) and CAN by "
        "python-can's serial interface. Prints one JSON line when ready.",
        epilog="examples:\n"
        "  pamd emulate --config config/rig-emulated.yaml &\n"
        "  pamd run --config config/rig-emulated.yaml --duration 30\n\n"
        "  pamd emulate --config config/rig-nidaq-emulated.yaml --realtime-priority 1 &\n"
        "  pamd run --config config/rig-nidaq-emulated.yaml --duration 15 --profile sine")
    p.add_argument("--config", metavar="FILE", required=True, help="the rig config to emulate")
    p.add_argument("--seed", type=int, default=1, help="sensor noise seed (1)")
    p.add_argument("--load", action="append", default=[], metavar="MUSCLE=KG",
                   help="true hanging load of a muscle (default: the config's load_kg)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    p.add_argument("--realtime-priority", type=int, default=0, metavar="N",
                   choices=range(0, 100),
                   help="run the emulated devices (and any socat links) at SCHED_FIFO N "
                   "(0: normal priority, the default). Real I/O modules and encoders have "
                   "CPUs of their own; on a busy PC an emulator at normal priority is "
                   "starved and answers late, which faults the daemon for the emulator's "
                   "sake. Give it a priority below the daemon's loop (1 is enough) when "
                   "testing pamd on a shared machine. The closing statistics say how late "
                   "the devices were (`lateness`).")
    p.set_defaults(func=run)


def _loads(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, _, kg = item.partition("=")
        try:
            out[name] = float(kg)
        except ValueError:
            raise SystemExit(f"pamd emulate: --load wants MUSCLE=KG, got {item!r}") from None
    return out


def run(args: argparse.Namespace) -> int:
    from pamd.emulate.rig import EmulatedRig

    cfg = load_config(args.config)
    # one emulator per device: a second one would take over the first's pty links
    # (RigBusy naming the first, before anything is made)
    locks = RunLocks(emulated_devices(cfg), cfg.rig.rig_id)
    locks.acquire()
    try:
        return _serve(args, cfg, EmulatedRig)
    finally:
        locks.release()


def emulated_devices(cfg: LoadedConfig) -> list[str]:
    """What an emulator of `cfg` serves, as lock names: "emulator of" each device the
    daemon would open (its drivers' claims)."""
    return [f"emulator of {claim}" for d in cfg.rig.drivers
            for claim in load_driver_class(d.type)(d.name, d.options).claims()]


def _serve(args: argparse.Namespace, cfg: LoadedConfig, make: type) -> int:
    from pamd.emulate.rig import realtime_priority

    if getattr(args, "realtime_priority", 0) > 0:
        refused = realtime_priority(args.realtime_priority)
        if refused is not None:
            print(f"pamd emulate: {refused}", file=sys.stderr, flush=True)
    rig = make(cfg, seed=args.seed, loads_kg=_loads(args.load))
    done = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        done.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
    try:
        rig.start()
    except (OSError, RuntimeError) as exc:  # a port taken, socat missing: said, no trace
        raise DriverError(f"the emulated rig of {cfg.path} cannot start: {exc}") from None
    try:
        ready = {"ready": True, "endpoints": rig.endpoints, "notices": rig.notices,
                 "true_length_mm": rig.plant.true_lengths_mm()}
        print(json.dumps(ready), flush=True)
        t0 = time.monotonic()
        while not done.wait(0.2):
            if args.duration is not None and time.monotonic() - t0 >= args.duration:
                break
    finally:
        rig.stop()
    stats = {"stopped": True, "physics_steps": rig.plant.steps,
             "modbus_requests": {k: d.requests for k, d in rig.modbus.items()},
             "watchdog_trips": {k: d.trips for k, d in rig.modbus.items()},
             "tpdo_frames": {k: e.sent for k, e in rig.encoders.items()},
             "nidaq": {k: {"calls": d.calls, "sample_clocks_waited": d.waits,
                           "sample_clocks_missed": d.late_clocks, "late_writes": d.late_writes}
                       for k, d in rig.nidaq.items()}}
    if hasattr(rig, "lateness"):
        stats["lateness"] = rig.lateness()
    print(json.dumps(stats), flush=True)
    sys.stdout.flush()
    return 0

"""`pamd router --zenoh-config FILE`: a Zenoh router (a session in router mode) for a
lab: the daemon and the clients connect to it, and its access control decides who may
do what (config/zenoh/lab-router.json5: mutual TLS, an `operator` role with state,
status and commands, a `viewer` role with state and status only). No Zenoh router
binary is needed. Runs until Ctrl-C or SIGTERM."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from types import FrameType

from pamd.wire import cleartext, zconf
from pamd.wire.zconf import NoDaemon


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("router", help="run a Zenoh router (for a lab with TLS and access "
                       "control)", description=__doc__)
    p.add_argument("--zenoh-config", metavar="FILE", required=True,
                   help="the router's Zenoh config (JSON5), e.g. "
                   "config/zenoh/lab-router.json5")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    p.add_argument("--allow-cleartext", action="store_true", help="listen on or connect "
                   "to an endpoint beyond loopback without TLS (plain tcp/0.0.0.0:..., "
                   "tcp/<LAN address>:...): refused otherwise, since everything the lab's "
                   "daemons and clients say crosses the network in clear; warned at start")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import zenoh


    cfg = zconf.router_config(args.zenoh_config)
    warnings = cleartext.judge([cleartext.Exposure(
        f"the router {'listens on' if which == 'listen' else 'connects to'}", e,
        "everything the lab's daemons and clients say", "tls/... endpoints, as "
        "config/zenoh/lab-router.json5", args.zenoh_config,
        zconf.endpoint_line(args.zenoh_config, e), f"{which}/endpoints")
        for which in ("listen", "connect") for e in zconf.cleartext_beyond_loopback(cfg, which)],
        args.allow_cleartext, cleartext.ROUTER_FLAG)
    try:
        session = zenoh.open(cfg)
    except Exception as exc:
        raise NoDaemon(f"router: {zconf.open_error(exc, cfg)}") from None
    done = threading.Event()

    def stop(signum: int, frame: FrameType | None) -> None:
        done.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, stop)
        signal.signal(signal.SIGTERM, stop)
    eps = ", ".join(zconf.endpoints(cfg, "listen"))
    print(f"pamd router: zid {session.zid()}, listening on {eps}", flush=True)
    for w in warnings:
        print(f"pamd router: WARNING: {w}", file=sys.stderr, flush=True)
    try:
        done.wait(args.duration)
    finally:
        closer = threading.Thread(target=session.close, daemon=True)
        closer.start()
        closer.join(3.0)
    print("pamd router: stopped", flush=True)
    return 0

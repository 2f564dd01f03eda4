"""`pamd safe-outputs` (the service's second line, run by ExecStopPost=) and `pamd
install-service` (the unit, its user and directories)."""

from __future__ import annotations

import argparse
import logging
import os

from pamd.daemon.service.install import install
from pamd.daemon.service.safe_outputs import replay
from pamd.daemon.service.state import SAFE_OUTPUTS_FILE, StateFileError, read_safe_outputs
from pamd.wire.errors import PamdError


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "safe-outputs", help="write the last known-good safe outputs to the devices",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write the safe outputs the daemon last saved (each valve at its "
        "muscle's safe pressure, exhaust valves open only where that is 0) straight to "
        "the devices, without the daemon and without the config: systemd runs it after "
        "every stop, crash or failed start (ExecStopPost=). The simulated rig has no "
        "device to reach and is skipped.",
        epilog="examples:\n"
        "  pamd safe-outputs --state-dir /var/lib/pamd\n"
        "  pamd safe-outputs --file my-rig.safe-outputs.json --dry-run\n\n"
        "exit codes: 0 written (or nothing saved yet), 2 unreadable file, 3 a device "
        "was not reached")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--state-dir", metavar="DIR",
                       help=f"the daemon's state directory (reads DIR/{SAFE_OUTPUTS_FILE})")
    where.add_argument("--file", metavar="FILE", help="a saved safe-outputs file (the "
                       "daemon's default beside a config: <config name>.safe-outputs.json)")
    p.add_argument("--timeout", type=float, default=5.0, metavar="S",
                   help="wait this long for each device (5)")
    p.add_argument("--dry-run", action="store_true", help="show what would be written")
    p.set_defaults(func=safe_outputs)

    q = sub.add_parser(
        "install-service", help="install the systemd unit, its user and directories",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Install pamd as a systemd service: /etc/systemd/system/pamd.service "
        "(ExecStart= this pamd), the pamd system user (sysusers.d, in group dialout), "
        "/var/lib/pamd (tmpfiles.d); then systemd-sysusers, systemd-tmpfiles and "
        "systemctl daemon-reload. It does not enable or start the service.",
        epilog="examples:\n"
        "  sudo pamd install-service --dry-run    # what it would do\n"
        "  sudo pamd install-service\n"
        "  pamd install-service --prefix /tmp/pkgroot   # files only, for packaging")
    q.add_argument("--prefix", default="/", metavar="DIR",
                   help="install below DIR; anything but / writes the files only (/)")
    q.add_argument("--dry-run", action="store_true", help="change nothing, say what it would do")
    q.add_argument("--pamd", metavar="PATH", help="the pamd executable for ExecStart= "
                   "(default: the one running this)")
    q.set_defaults(func=install_service)


def safe_outputs(args: argparse.Namespace) -> int:
    path = args.file or os.path.join(args.state_dir, SAFE_OUTPUTS_FILE)
    try:
        doc = read_safe_outputs(path)
    except StateFileError as exc:
        print(f"pamd safe-outputs: {exc}; nothing written")
        return exc.exit_code
    if doc is None:
        print(f"pamd safe-outputs: no saved safe outputs at {path} (the daemon never "
              "started with a valid config here, so it wrote nothing either); nothing to do")
        return 0
    if args.dry_run:
        for d in doc["drivers"]:
            for o in d["outputs"]:
                print(f"would write {d['type']} {d['name']!r} {o['channel']} = {o['raw']:g}"
                      f" ({o.get('signal', '')} {o.get('si', '')} {o.get('si_unit', '')})")
        return 0
    logging.getLogger("pamd").setLevel(logging.WARNING)
    try:
        return replay(doc, timeout_s=args.timeout,
                      say=lambda line: print(f"pamd safe-outputs: {line}", flush=True))
    except PamdError as exc:
        print(f"pamd safe-outputs: {exc}")
        return exc.exit_code


def install_service(args: argparse.Namespace) -> int:
    return install(prefix=args.prefix, dry_run=args.dry_run, pamd_path=args.pamd)

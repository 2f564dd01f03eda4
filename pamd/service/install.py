"""`pamd install-service`: put the unit, the sysusers.d and tmpfiles.d snippets in
place, create the user and the directories, and tell systemd; then say what is
left to do (the config, enabling the service). `--prefix DIR` writes the files
under DIR only (for packaging, or to look at them); `--dry-run` changes nothing
and prints what it would do.

The files come from the repository's systemd/ directory (installed with the
package as `pamd.service.units`); the unit's placeholder /opt/pamd/bin/pamd is
replaced by the pamd that runs this command.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from importlib import resources
from pathlib import Path

from pamd.config import load_config
from pamd.errors import ConfigError

PLACEHOLDER = "/opt/pamd/bin/pamd"
FILES = (  # (source in systemd/, target below the prefix)
    ("pamd.service", "etc/systemd/system/pamd.service"),
    ("pamd.sysusers.conf", "etc/sysusers.d/pamd.conf"),
    ("pamd.tmpfiles.conf", "etc/tmpfiles.d/pamd.conf"),
)
CONFIG = "etc/pamd/pamd.yaml"
STATE_DIR = "/var/lib/pamd"


def unit_text(name: str) -> str:
    """A file of systemd/: the source tree's (a checkout, an editable install), else
    the copy installed with the package."""
    path = Path(__file__).resolve().parents[2] / "systemd" / name
    if path.is_file():
        return path.read_text(encoding="utf-8")
    return resources.files("pamd.service.units").joinpath(name).read_text(encoding="utf-8")


def installed_pamd() -> str:
    """The pamd executable beside this interpreter (a venv's bin/), or on PATH."""
    beside = Path(sys.executable).parent / "pamd"
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    found = shutil.which("pamd")
    if found:
        return os.path.abspath(found)
    raise FileNotFoundError("cannot find the pamd executable; pass --pamd PATH")


def render(name: str, pamd_path: str) -> str:
    return unit_text(name).replace(PLACEHOLDER, pamd_path)


def install(prefix: str = "/", dry_run: bool = False, pamd_path: str | None = None,
            say: Callable[[str], None] = print,
            run: Callable[[list[str]], int] | None = None) -> int:
    """Install; returns the exit code. `run` executes a system command (tests)."""
    live = os.path.abspath(prefix) == "/"
    if live and not dry_run and os.geteuid() != 0:
        say("pamd install-service writes /etc and creates a system user: run it as root "
            "(sudo), or see what it would do with --dry-run, or write the files elsewhere "
            "with --prefix DIR")
        return 1
    pamd = pamd_path or installed_pamd()
    verb = "would write" if dry_run else "wrote"
    for src, rel in FILES:
        target = os.path.join(prefix, rel)
        text = render(src, pamd)
        if not dry_run:
            os.makedirs(os.path.dirname(target), exist_ok=True)
            tmp = target + ".new"
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(text)
            os.chmod(tmp, 0o644)
            os.replace(tmp, target)
        say(f"{verb} {target}")
    say(f"  ExecStart= {pamd} run --config /etc/pamd/pamd.yaml --state-dir {STATE_DIR}")
    commands = [["systemd-sysusers", "/etc/sysusers.d/pamd.conf"],
                ["systemd-tmpfiles", "--create", "/etc/tmpfiles.d/pamd.conf"],
                ["systemctl", "daemon-reload"]]
    code = 0
    for cmd in commands:
        line = " ".join(cmd)
        if not live:
            say(f"on the rig PC, run: {line}")
        elif dry_run:
            say(f"would run: {line}")
        elif shutil.which(cmd[0]) is None and run is None:
            say(f"{cmd[0]} not found: run `{line}` once systemd is there")
            code = 1
        else:
            rc = (run or _run)(cmd)
            say(f"ran: {line}" + ("" if rc == 0 else f" (FAILED, exit code {rc})"))
            code = code or (1 if rc else 0)
    _check_config(os.path.join(prefix, CONFIG), say)
    say("then: systemctl enable --now pamd; systemctl status pamd; journalctl -u pamd -f")
    return code


def _run(cmd: list[str]) -> int:
    return subprocess.run(cmd, check=False).returncode


def _check_config(path: str, say: Callable[[str], None]) -> None:
    """Say what the config still needs to run under the service's sandbox."""
    if not os.path.exists(path):
        say(f"next: put the rig config at {path} (`pamd check-config` it first), with "
            f"calibration_file: {STATE_DIR}/pamd.cal.yaml")
        return

    try:
        cfg = load_config(path)
    except ConfigError as exc:
        say(f"the config {path} does not validate; the service would not start:\n{exc}")
        return
    say(f"config {path}: valid (rig {cfg.rig.rig_id!r})")
    cal = cfg.calibration_path
    if not cal.startswith(STATE_DIR + "/"):
        say(f"  calibration file {cal} is read-only to the service (ProtectSystem=strict); "
            f"set calibration_file: {STATE_DIR}/pamd.cal.yaml")
    rec = cfg.rig.recording.dir
    if rec and os.path.isabs(rec) and not rec.startswith(STATE_DIR):
        say(f"  recording.dir {rec} is outside {STATE_DIR}: allow it with a drop-in "
            f"(systemctl edit pamd): [Service] ReadWritePaths={rec}")

"""`pamd install-service`: put the unit, the sysusers.d and tmpfiles.d snippets in
place, create the user and the directories, and tell systemd; then say what is
left to do (the config, enabling the service). `--prefix DIR` writes the files
under DIR only (for packaging, or to look at them); `--dry-run` changes nothing
and prints what it would do.

The files come from the repository's systemd/ directory (installed with the
package as `pamd.daemon.service.units`); the unit's placeholder /opt/pamd/bin/pamd is
replaced by the pamd that runs this command.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from importlib import resources
from pathlib import Path

from pamd.config import LoadedConfig, load_config
from pamd.wire.atomic import write_atomic
from pamd.wire.errors import ConfigError

PLACEHOLDER = "/opt/pamd/bin/pamd"
FILES = (  # (source in systemd/, target below the prefix)
    ("pamd.service", "etc/systemd/system/pamd.service"),
    ("pamd.sysusers.conf", "etc/sysusers.d/pamd.conf"),
    ("pamd.tmpfiles.conf", "etc/tmpfiles.d/pamd.conf"),
)
CONFIG = "etc/pamd/pamd.yaml"
STATE_DIR = "/var/lib/pamd"
RECORDINGS = f"{STATE_DIR}/recordings"  # made by pamd.tmpfiles.conf
#: what the unit's sandbox hides from the service, which setting does it, and the
#: drop-in setting that lets the service see it again (read-only where that is enough:
#: ProtectHome=read-only shows /home; a private /tmp is only undone by PrivateTmp=no)
HIDDEN = (
    (("/home", "/root", "/run/user"), "ProtectHome=yes hides /home, /root and /run/user "
     "from the service", "ProtectHome=read-only"),
    (("/tmp", "/var/tmp"), "PrivateTmp=yes gives the service a /tmp and /var/tmp of its "
     "own (empty)", "PrivateTmp=no"),
)


def _hidden(path: str) -> tuple[str, str] | None:
    path = os.path.abspath(path)
    for roots, why, relief in HIDDEN:
        if any(path == r or path.startswith(r + "/") for r in roots):
            return why, relief
    return None


def hidden_by_sandbox(path: str) -> str | None:
    """Why the service cannot see `path` (None: it can): the unit's ProtectHome= and
    PrivateTmp=."""
    found = _hidden(path)
    return found[0] if found else None


def sandbox_relief(path: str) -> str | None:
    """The drop-in setting that lets the service see `path` (None: it sees it)."""
    found = _hidden(path)
    return found[1] if found else None


def executable_paths(pamd: str) -> list[str]:
    """What ExecStart= needs to reach: the pamd script, where its links lead, its
    interpreter (the #! line of a console script) and where that leads."""
    paths = [pamd, os.path.realpath(pamd)]
    try:
        with open(pamd, "rb") as fh:
            first = fh.readline(512)
    except OSError:
        first = b""
    if first.startswith(b"#!"):
        interp = first[2:].decode(errors="replace").strip().split()
        if interp and interp[0].startswith("/") and not interp[0].endswith("/env"):
            paths += [interp[0], os.path.realpath(interp[0])]
    return list(dict.fromkeys(paths))


def unit_text(name: str) -> str:
    """A file of systemd/: the source tree's (a checkout, an editable install), else
    the copy installed with the package."""
    path = Path(__file__).resolve().parents[3] / "systemd" / name
    if path.is_file():
        return path.read_text(encoding="utf-8")
    return resources.files("pamd.daemon.service.units").joinpath(name).read_text(encoding="utf-8")


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
    done = "would write" if dry_run else "wrote"
    for src, rel in FILES:
        target = os.path.join(prefix, rel)
        text = render(src, pamd)
        if not dry_run:
            os.makedirs(os.path.dirname(target), exist_ok=True)
            write_atomic(target, text, file_mode=0o644)
        say(f"{done} {target}")
    say(f"  ExecStart= {pamd} run --config /etc/pamd/pamd.yaml --state-dir {STATE_DIR}")
    _check_executable(pamd, say)
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


def _check_executable(pamd: str, say: Callable[[str], None]) -> None:
    """Warn when the service could not start the pamd it is given."""
    for path in executable_paths(pamd):
        why = hidden_by_sandbox(path)
        if why:
            say(f"WARNING: the service cannot start {pamd}: {path} is hidden from it ({why}). "
                "Install pamd where the service sees it, e.g. python3 -m venv /opt/pamd && "
                "/opt/pamd/bin/pip install . && sudo /opt/pamd/bin/pamd install-service; "
                f"or relax it in a drop-in (systemctl edit pamd: [Service] "
                f"{sandbox_relief(path)})")
            return


def _check_config(path: str, say: Callable[[str], None]) -> None:
    """Say what the config still needs to run under the service's sandbox."""
    if not os.path.exists(path):
        say(f"next: put the rig config at {path} (`pamd check-config` it first), with "
            f"recording: {{dir: {RECORDINGS}}} (the service records only where its config "
            f"says); its fault, safe outputs and datums go to {STATE_DIR}")
        return

    try:
        cfg = load_config(path)
    except ConfigError as exc:
        say(f"the config {path} does not validate; the service would not start:\n{exc}")
        return
    say(f"config {path}: valid (rig {cfg.rig.rig_id!r})")
    cal = cfg.calibration_path
    if cal and not cal.startswith(STATE_DIR + "/"):
        say(f"  calibration file {cal} is read-only to the service (ProtectSystem=strict); "
            f"remove calibration_file (the datums then go to {STATE_DIR}) or set "
            f"calibration_file: {STATE_DIR}/calibration.yaml")
    rec = cfg.rig.recording.dir
    if not rec:
        say(f"  the service will not record: add recording: {{dir: {RECORDINGS}}}")
    elif os.path.isabs(rec) and not rec.startswith(STATE_DIR) and not hidden_by_sandbox(rec):
        say(f"  recording.dir {rec} is outside {STATE_DIR}: allow it with a drop-in "
            f"(systemctl edit pamd): [Service] ReadWritePaths={rec}")
    for key, used in _paths_used(cfg):
        why = hidden_by_sandbox(used)
        if why:
            say(f"  WARNING: {key} {used} is hidden from the service ({why}): move it "
                f"(e.g. to /etc/pamd or {STATE_DIR})")


def _paths_used(cfg: LoadedConfig) -> list[tuple[str, str]]:
    """Every absolute path the config makes the service open: files it names (relative
    ones are resolved as pamd does) and the drivers' device paths."""
    base = os.path.dirname(os.path.abspath(cfg.path))
    rig = cfg.rig
    found: list[tuple[str, str]] = []
    if rig.recording.dir and os.path.isabs(rig.recording.dir):
        found.append(("recording.dir", rig.recording.dir))
    if cfg.calibration_path:
        found.append(("calibration_file", cfg.calibration_path))
    if rig.telemetry.zenoh_config:
        found.append(("telemetry.zenoh_config", os.path.join(base, rig.telemetry.zenoh_config)))
    if rig.telemetry.models_dir:
        found.append(("telemetry.models_dir", os.path.join(base, rig.telemetry.models_dir)))
    for m in rig.muscles:
        if m.model_file:
            found.append((f"muscles[{m.name}].model_file", os.path.join(base, m.model_file)))
    for d in rig.drivers:
        for key, value in _strings(d.options):
            if value.startswith("/"):
                found.append((f"drivers[{d.name}].options.{key}", value))
    return found


def _strings(options: object, prefix: str = "") -> list[tuple[str, str]]:
    """(key, value) of every string in a driver's options (dataclasses, lists, dicts)."""
    if isinstance(options, str):
        return [(prefix, options)]
    if dataclasses.is_dataclass(options) and not isinstance(options, type):
        return [kv for f in dataclasses.fields(options)
                for kv in _strings(getattr(options, f.name), _join(prefix, f.name))]
    if isinstance(options, dict):
        return [kv for k, v in options.items() for kv in _strings(v, _join(prefix, str(k)))]
    if isinstance(options, (list, tuple)):
        return [kv for i, v in enumerate(options) for kv in _strings(v, f"{prefix}[{i}]")]
    return []


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key

"""The unit and its snippets: `systemd-analyze verify` passes with no output at all
(it exits 0 on unknown keys and bad values and only warns, so any output fails);
the unit says what the issue asks; sysusers.d and tmpfiles.d snippets apply to a
scratch root; `pamd install-service` writes them with ExecStart= the real pamd."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pamd.daemon.service.install import PLACEHOLDER, install

REPO = Path(__file__).resolve().parents[2]
UNIT = REPO / "systemd" / "pamd.service"
SYSUSERS = REPO / "systemd" / "pamd.sysusers.conf"
TMPFILES = REPO / "systemd" / "pamd.tmpfiles.conf"


def settings(text: str) -> dict[str, list[str]]:
    """Key -> values (in order) of a unit file, any section."""
    out: dict[str, list[str]] = {}
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith(("#", ";", "[")):
            continue
        key, _, value = line.partition("=")
        out.setdefault(key.strip(), []).append(value.strip())
    return out


def seconds(value: str) -> float:
    m = re.fullmatch(r"(\d+)(s|min)?", value)
    assert m, value
    return int(m.group(1)) * (60 if m.group(2) == "min" else 1)


def test_systemd_analyze_verify_says_nothing(tmp_path: Path, systemd_analyze: str) -> None:
    exe = shutil.which("pamd") or sys.executable  # an existing path for ExecStart=
    unit = tmp_path / "pamd.service"
    unit.write_text(UNIT.read_text().replace(PLACEHOLDER, exe))
    r = subprocess.run([systemd_analyze, "verify", str(unit)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0 and r.stdout == "" and r.stderr == "", r.stdout + r.stderr


def test_the_unit_says_what_the_rig_needs() -> None:
    s = settings(UNIT.read_text())
    one = {k: v[-1] for k, v in s.items()}
    assert one["Type"] == "notify" and one["NotifyAccess"] == "main"
    assert one["ExecStart"] == (f"{PLACEHOLDER} run --config /etc/pamd/pamd.yaml "
                                "--state-dir /var/lib/pamd")
    assert one["ExecStopPost"] == f"{PLACEHOLDER} safe-outputs --state-dir /var/lib/pamd"
    assert one["ExecReload"] == "/bin/kill -HUP $MAINPID"
    assert seconds(one["WatchdogSec"]) > 0
    assert one["Restart"] == "on-failure"
    assert seconds(one["StartLimitIntervalSec"]) > 0 and int(one["StartLimitBurst"]) > 0
    assert one["User"] == "pamd" and "dialout" in one["SupplementaryGroups"].split()
    assert int(one["LimitRTPRIO"]) >= 80 and one["LimitMEMLOCK"] == "infinity"
    assert one["StateDirectory"] == "pamd" and one["ConfigurationDirectory"] == "pamd"
    # the rig locks: where a `pamd run` started by hand looks too (pamd.daemon.service.riglock)
    assert one["RuntimeDirectory"] == "pamd" and one["RuntimeDirectoryPreserve"] == "yes"
    assert one["NoNewPrivileges"] == "yes" and one["ProtectSystem"] == "strict"
    assert one["ProtectHome"] == "yes" and one["PrivateTmp"] == "yes"
    assert "RestrictRealtime" not in s  # only the loop's thread takes SCHED_FIFO
    assert "PrivateDevices" not in s and "ProtectClock" not in s  # serial, CAN devices
    # the safe-state ramp (30 s at most) and finalising the recording (60 s at most)
    assert seconds(one["TimeoutStopSec"]) >= 30 + 60
    assert one["KillMode"] == "mixed"  # SIGTERM to pamd; it stops its io process itself


def test_sysusers_and_tmpfiles_apply_to_a_scratch_root(tmp_path: Path) -> None:
    if shutil.which("systemd-sysusers") is None or shutil.which("systemd-tmpfiles") is None:
        pytest.fail("systemd-sysusers/systemd-tmpfiles not installed: run .ci/setup-tests, "
                    "or apt-get install systemd", pytrace=False)
    if os.geteuid() != 0:
        pytest.skip("creating files owned by the pamd user needs root")
    etc = tmp_path / "etc"
    (etc / "sysusers.d").mkdir(parents=True)
    (etc / "tmpfiles.d").mkdir()
    for name in ("passwd", "group"):
        shutil.copy(f"/etc/{name}", etc / name)
    shutil.copy(SYSUSERS, etc / "sysusers.d" / "pamd.conf")
    shutil.copy(TMPFILES, etc / "tmpfiles.d" / "pamd.conf")
    r = subprocess.run(["systemd-sysusers", f"--root={tmp_path}"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    passwd = (etc / "passwd").read_text()
    user = next(ln for ln in passwd.splitlines() if ln.startswith("pamd:"))
    assert user.split(":")[5] == "/var/lib/pamd"
    dialout = next(ln for ln in (etc / "group").read_text().splitlines()
                   if ln.startswith("dialout:"))
    assert "pamd" in dialout.split(":")[3].split(",")
    r = subprocess.run(["systemd-tmpfiles", f"--root={tmp_path}", "--create"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    st = (tmp_path / "var" / "lib" / "pamd").stat()
    assert st.st_mode & 0o777 == 0o750 and st.st_uid == int(user.split(":")[2])
    assert (tmp_path / "var" / "lib" / "pamd" / "recordings").is_dir()


def test_install_service_writes_the_files_with_the_real_pamd(tmp_path: Path) -> None:
    lines: list[str] = []
    root = tmp_path / "root"
    assert install(prefix=str(root), dry_run=True, pamd_path="/x/bin/pamd",
                   say=lines.append) == 0
    assert not root.exists() and any("would write" in ln for ln in lines)
    lines.clear()
    assert install(prefix=str(root), pamd_path="/x/bin/pamd", say=lines.append) == 0
    unit = (root / "etc/systemd/system/pamd.service").read_text()
    assert PLACEHOLDER not in unit
    assert "ExecStart=/x/bin/pamd run --config /etc/pamd/pamd.yaml" in unit
    assert "ExecStopPost=/x/bin/pamd safe-outputs --state-dir /var/lib/pamd" in unit
    assert (root / "etc/sysusers.d/pamd.conf").read_text() == SYSUSERS.read_text()
    assert (root / "etc/tmpfiles.d/pamd.conf").read_text() == TMPFILES.read_text()
    text = "\n".join(lines)
    assert "systemd-sysusers /etc/sysusers.d/pamd.conf" in text  # told, not run
    assert "put the rig config at" in text and "systemctl enable --now pamd" in text
    assert "recording: {dir: /var/lib/pamd/recordings}" in text  # the service's own
    # a config already there is checked against the sandbox
    cfg = root / "etc/pamd/pamd.yaml"
    cfg.parent.mkdir(parents=True)
    cfg.write_text((REPO / "config" / "sim.yaml").read_text())
    lines.clear()
    install(prefix=str(root), pamd_path="/x/bin/pamd", say=lines.append)
    assert any("the service will not record: add recording: {dir: /var/lib/pamd/recordings}"
               in ln for ln in lines)


def test_install_service_cli_dry_run() -> None:
    r = subprocess.run([sys.executable, "-m", "pamd", "install-service", "--dry-run"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "would write /etc/systemd/system/pamd.service" in r.stdout
    assert "would run: systemctl daemon-reload" in r.stdout

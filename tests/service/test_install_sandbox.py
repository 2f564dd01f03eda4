"""`pamd install-service` warns about what the unit's sandbox hides from the service
(ProtectHome=yes: /home, /root, /run/user; PrivateTmp=yes: /tmp, /var/tmp): the pamd it
would start, that script's Python, the files the config names and its devices; and its
"next:" hint says all the config needs (the recording directory)."""

from __future__ import annotations

from pathlib import Path

import yaml

from pamd.daemon.service.install import (
    executable_paths,
    hidden_by_sandbox,
    install,
    sandbox_relief,
)

from .conftest import sim_dict

REPO = Path(__file__).resolve().parents[2]


def test_what_the_sandbox_hides() -> None:
    assert "ProtectHome=yes" in (hidden_by_sandbox("/home/ana/venv/bin/pamd") or "")
    assert "ProtectHome=yes" in (hidden_by_sandbox("/root/.pyenv/bin/python3") or "")
    assert "PrivateTmp=yes" in (hidden_by_sandbox("/tmp/pamd-emu/rtu") or "")
    assert "PrivateTmp=yes" in (hidden_by_sandbox("/var/tmp/x") or "")
    for seen in ("/opt/pamd/bin/pamd", "/usr/bin/python3", "/homework/pamd", "/dev/ttyUSB0",
                 "/var/lib/pamd/recordings"):
        assert hidden_by_sandbox(seen) is None, seen


def test_the_script_and_its_python_are_checked(tmp_path: Path) -> None:
    script = tmp_path / "pamd"
    script.write_text("#!/home/ana/venv/bin/python3\nimport pamd\n")
    assert "/home/ana/venv/bin/python3" in executable_paths(str(script))


def test_a_pamd_under_home_is_warned_about(tmp_path: Path) -> None:
    lines: list[str] = []
    install(prefix=str(tmp_path / "root"), pamd_path="/home/ana/venv/bin/pamd",
            say=lines.append)
    warned = [ln for ln in lines if ln.startswith("WARNING")]
    assert len(warned) == 1, lines
    assert "/home/ana/venv/bin/pamd" in warned[0] and "ProtectHome=yes" in warned[0]
    assert "/opt/pamd" in warned[0]  # what to do instead
    lines.clear()
    install(prefix=str(tmp_path / "root2"), pamd_path="/opt/pamd/bin/pamd", say=lines.append)
    assert not [ln for ln in lines if ln.startswith("WARNING")], lines


def test_the_drop_in_suggested_is_the_one_that_shows_the_path(tmp_path: Path) -> None:
    """ProtectHome=read-only shows /home to the service, but not a private /tmp: a pamd
    under /tmp needs PrivateTmp=no (issue 40: the dry run suggested ProtectHome there)."""
    assert sandbox_relief("/home/ana/venv/bin/pamd") == "ProtectHome=read-only"
    assert sandbox_relief("/tmp/venv/bin/pamd") == "PrivateTmp=no"
    assert sandbox_relief("/opt/pamd/bin/pamd") is None
    for where, relief, not_this in (("/tmp/venv/bin/pamd", "PrivateTmp=no", "ProtectHome"),
                                    ("/home/ana/venv/bin/pamd", "ProtectHome=read-only",
                                     "PrivateTmp=no")):
        lines: list[str] = []
        install(prefix=str(tmp_path / where.replace("/", "_")), pamd_path=where,
                say=lines.append)
        warned = next(ln for ln in lines if ln.startswith("WARNING"))
        assert f"[Service] {relief})" in warned and not_this not in warned, warned


def test_the_hint_names_the_recording_directory(tmp_path: Path) -> None:
    lines: list[str] = []
    install(prefix=str(tmp_path / "root"), pamd_path="/opt/pamd/bin/pamd", say=lines.append)
    nxt = next(ln for ln in lines if ln.startswith("next:"))
    assert "recording: {dir: /var/lib/pamd/recordings}" in nxt


def test_files_and_devices_the_config_names_under_tmp_or_home(tmp_path: Path) -> None:
    root = tmp_path / "root"
    cfg = root / "etc" / "pamd" / "pamd.yaml"
    cfg.parent.mkdir(parents=True)
    emulated = yaml.safe_load((REPO / "config" / "rig-emulated.yaml").read_text())
    emulated["recording"] = {"dir": "/var/lib/pamd/recordings"}
    for drv in emulated["drivers"]:  # its pty links (an option: the shipped ones are sockets)
        o = drv["options"]
        if drv["name"] == "lc2":
            o.pop("host"), o.pop("port")
            o.update(transport="rtu", serial_port="/tmp/pamd-emu/rtu")
        elif drv["name"] == "enc":
            o.pop("host"), o.pop("port")
            o.update(interface="serial", channel="/tmp/pamd-emu/can")
    cfg.write_text(yaml.safe_dump(emulated, sort_keys=False))
    lines: list[str] = []
    install(prefix=str(root), pamd_path="/opt/pamd/bin/pamd", say=lines.append)
    warned = "\n".join(ln for ln in lines if "WARNING" in ln)
    # the emulated rig's pty links are in /tmp: the service would not see them
    assert "drivers[lc2].options.serial_port /tmp/pamd-emu/rtu" in warned
    assert "drivers[enc].options.channel /tmp/pamd-emu/can" in warned
    assert "PrivateTmp=yes" in warned
    assert "will not record" not in "\n".join(lines)  # it has its recording.dir

    d = sim_dict(recording={"dir": "/home/ana/runs"})
    d["muscles"][0]["model_file"] = "/home/ana/model.json"
    cfg.write_text(yaml.safe_dump(d, sort_keys=False))
    lines.clear()
    install(prefix=str(root), pamd_path="/opt/pamd/bin/pamd", say=lines.append)
    text = "\n".join(lines)
    assert "recording.dir /home/ana/runs is hidden" in text
    assert "muscles[m1].model_file /home/ana/model.json is hidden" in text
    assert "ReadWritePaths=/home/ana/runs" not in text  # a drop-in would not help there

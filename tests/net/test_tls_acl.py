"""The lab setup, for real: `pamd router` with the shipped lab-router.json5 (mutual
TLS, user/password, access control), a daemon and clients that reach it with the
shipped lab-daemon.json5 / lab-client.json5 (only the file paths and port changed).
An operator sees state and status and commands; a viewer sees state and status, and
its commands get nowhere; a certificate from another CA, no certificate, or a wrong
password does not connect at all. Throwaway certificates come from openssl."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from .conftest import (
    free_port,
    pamd_cli,
    rig_config,
    wait_listening,
    wait_ready,
    wait_until,
)

REPO = Path(__file__).resolve().parents[2]
ZCONF = REPO / "config" / "zenoh"
USERS = {"rig-sim": "daemon-pw", "ana": "operator-pw", "bob": "viewer-pw"}

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None, reason="needs openssl")


def _openssl(*args: str) -> None:
    subprocess.run(["openssl", *args], check=True, capture_output=True, timeout=60)


def make_certs(d: Path) -> None:
    """A lab CA and leaf certificates (EC P-256, valid 2 days), plus a rogue CA."""
    ec = ("-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes")
    for ca in ("ca", "rogue-ca"):
        _openssl("req", "-x509", *ec, "-keyout", str(d / f"{ca}.key"), "-out",
                 str(d / f"{ca}.pem"), "-days", "2", "-subj", f"/CN=pamd-test-{ca}")
    (d / "san.ext").write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    for name, cn, ca in (("router", "localhost", "ca"), ("daemon", "pamd-daemon", "ca"),
                         ("operator", "operator", "ca"), ("viewer", "viewer", "ca"),
                         ("rogue", "operator", "rogue-ca")):
        _openssl("req", *ec, "-keyout", str(d / f"{name}.key"), "-out", str(d / f"{name}.csr"),
                 "-subj", f"/CN={cn}")
        _openssl("x509", "-req", "-in", str(d / f"{name}.csr"), "-CA", str(d / f"{ca}.pem"),
                 "-CAkey", str(d / f"{ca}.key"), "-CAcreateserial", "-out",
                 str(d / f"{name}.pem"), "-days", "2", "-extfile", str(d / "san.ext"))
    (d / "users.txt").write_text("".join(f"{u}:{p}\n" for u, p in USERS.items()))


def derive(src: str, out: Path, changes: dict[str, Any], drop: tuple[str, ...] = ()) -> Path:
    """A shipped config with its paths and endpoints changed (what a lab edits)."""
    import zenoh

    cfg = zenoh.Config.from_file(str(ZCONF / src))
    for key, value in changes.items():
        cfg.insert_json5(key, json.dumps(value))
    data = json.loads(str(cfg))
    for key in drop:
        *parents, last = key.split("/")
        node = data
        for p in parents:
            node = node[p]
        node[last] = None
    out.write_text(json.dumps(data))
    return out


def client_conf(d: Path, name: str, cert: str, user: str, password: str, port: int,
                ca: str = "ca", no_cert: bool = False) -> Path:
    tls = "transport/link/tls"
    return derive("lab-client.json5", d / f"{name}.json5", {
        "connect/endpoints": [f"tls/localhost:{port}"],
        f"{tls}/root_ca_certificate": str(d / f"{ca}.pem"),
        f"{tls}/connect_certificate": str(d / f"{cert}.pem"),
        f"{tls}/connect_private_key": str(d / f"{cert}.key"),
        "transport/auth/usrpwd/user": user, "transport/auth/usrpwd/password": password,
    }, drop=(f"{tls}/connect_certificate", f"{tls}/connect_private_key") if no_cert else ())


def test_operator_and_viewer_roles_with_mutual_tls(tmp_path: Path, daemons: Any,
                                                   agents: Any) -> None:
    make_certs(tmp_path)
    port = free_port()
    tls = "transport/link/tls"
    router_conf = derive("lab-router.json5", tmp_path / "router.json5", {
        "listen/endpoints": [f"tls/127.0.0.1:{port}"],
        f"{tls}/root_ca_certificate": str(tmp_path / "ca.pem"),
        f"{tls}/listen_certificate": str(tmp_path / "router.pem"),
        f"{tls}/listen_private_key": str(tmp_path / "router.key"),
        "transport/auth/usrpwd/dictionary_file": str(tmp_path / "users.txt")})
    daemon_conf = derive("lab-daemon.json5", tmp_path / "daemon.json5", {
        "connect/endpoints": [f"tls/localhost:{port}"],
        f"{tls}/root_ca_certificate": str(tmp_path / "ca.pem"),
        f"{tls}/connect_certificate": str(tmp_path / "daemon.pem"),
        f"{tls}/connect_private_key": str(tmp_path / "daemon.key"),
        "transport/auth/usrpwd/user": "rig-sim",
        "transport/auth/usrpwd/password": USERS["rig-sim"]})
    op_conf = client_conf(tmp_path, "operator-ana", "operator", "ana", USERS["ana"], port)
    view_conf = client_conf(tmp_path, "viewer-bob", "viewer", "bob", USERS["bob"], port)

    router = subprocess.Popen([sys.executable, "-m", "pamd", "router", "--zenoh-config",
                               str(router_conf)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    try:
        wait_listening(port)
        # the daemon listens on nothing: a free port it never uses stays in its config
        d = daemons("--config", rig_config(tmp_path, free_port()), "--zenoh-config",
                    daemon_conf)
        op = agents("--zenoh-config", str(op_conf))
        view = agents("--zenoh-config", str(view_conf))
        assert op.hello.get("ready") and view.hello.get("ready"), (op.hello, view.hello)
        wait_ready(op, "sim", d)

        # the operator: state, status, commands
        op.call("subscribe", name="state", key="pamd/sim/state/m1")
        assert op.call("until", name="state", field="pressure_bar", seconds=30)["met"]
        assert op.call("rigs") == {"rigs": ["sim"]}
        v = op.call("cmd", rig="sim", verb="setpoint", payload={"muscle": "m1", "bar": 1.5})
        assert v.get("ok") is True, v
        before = wait_until(lambda: (s := op.call("status", rig="sim"))["state"] == "RUNNING"
                            and s, 30, "RUNNING in the status")

        # the viewer: state and status, but its commands reach nothing
        view.call("subscribe", name="state", key="pamd/sim/state/m1")
        assert view.call("until", name="state", field="pressure_bar", seconds=30)["met"]
        assert view.call("status", rig="sim")["ok"] is True
        assert view.call("rigs") == {"rigs": ["sim"]}
        for verb, payload in (("estop", {}), ("setpoint", {"muscle": "m1", "bar": 0.0}),
                              ("stop", {})):
            v = view.call("cmd", rig="sim", verb=verb, payload=payload, timeout=2.0)
            assert "no answer on pamd/sim/cmd/" in v.get("no_daemon", ""), v
        after = op.call("status", rig="sim")
        assert after["state"] == "RUNNING" and after["fault"] is None
        assert after["io"]["commands"] == before["io"]["commands"]  # none arrived
        r = pamd_cli("cmd", "--zenoh-config", str(view_conf), "--timeout", "2", "hold")
        assert r.returncode == 7 and "not allowed" in r.stderr, r.stderr
        r = pamd_cli("status", "--zenoh-config", str(op_conf), "--json")
        assert r.returncode == 0 and json.loads(r.stdout)["state"] == "RUNNING", r.stderr
        r = pamd_cli("cmd", "--zenoh-config", str(op_conf), "stop")
        assert r.returncode == 0 and json.loads(r.stdout)["ok"], r.stdout + r.stderr

        # wrong credentials do not connect at all
        for name, cert, user, pw, ca, no_cert in (
                ("rogue", "rogue", "ana", USERS["ana"], "ca", False),  # another CA's cert
                ("nocert", "operator", "ana", USERS["ana"], "ca", True),  # no cert
                ("wrongpw", "operator", "ana", "guess", "ca", False)):  # wrong password
            conf = client_conf(tmp_path, name, cert, user, pw, port, ca, no_cert)
            bad = agents("--zenoh-config", str(conf))
            assert "cannot connect" in bad.hello.get("error", ""), (name, bad.hello)
        assert d.stop() == 0, d.log()[-3000:]
    finally:
        router.terminate()
        router.communicate(timeout=30)

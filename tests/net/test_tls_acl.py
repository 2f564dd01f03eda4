"""The lab setup, for real: `pamd router` with the shipped lab-router.json5 (mutual
TLS, user/password, access control), a daemon and clients that reach it with the
shipped lab-daemon.json5 / lab-client.json5 (only the file paths and port changed).
An operator sees state and status and commands; a viewer sees state and status, and
its commands get nowhere; a certificate from another CA, no certificate, or a wrong
password does not connect at all. Throwaway certificates come from openssl."""

from __future__ import annotations

import json
import re
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


#: the how-to page that gives the lab's recipe (the docs site: docs/how-to/)
RECIPE_PAGE = REPO / "docs" / "how-to" / "lab-network.md"


def readme_recipe() -> str:
    """The lab-network page's openssl commands, exactly as written there."""
    blocks = re.findall(r"```sh\n(.*?)```", RECIPE_PAGE.read_text(), re.S)
    return next(b for b in blocks if "openssl req -x509" in b)


def make_certs(d: Path) -> dict[str, str]:
    """Run the page's recipe verbatim in `d`; returns its users and passwords."""
    if shutil.which("openssl") is None:
        pytest.fail("openssl is not installed: the docs' certificate recipe needs it "
                    "(apt-get install openssl, or run .ci/setup-tests)")
    d.mkdir(parents=True, exist_ok=True)
    subprocess.run(["sh", "-eu", "-c", readme_recipe()], cwd=d, check=True,
                   capture_output=True, timeout=120)
    return dict(line.split(":", 1) for line in (d / "users.txt").read_text().split())


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
                certs: Path | None = None, no_cert: bool = False) -> Path:
    """A client of the router on `port`: the lab's CA, and `cert` from `certs` (default:
    the lab's own certificates in `d`)."""
    tls = "transport/link/tls"
    certs = certs or d
    return derive("lab-client.json5", d / f"{name}.json5", {
        "connect/endpoints": [f"tls/localhost:{port}"],
        f"{tls}/root_ca_certificate": str(d / "ca.pem"),
        f"{tls}/connect_certificate": str(certs / f"{cert}.pem"),
        f"{tls}/connect_private_key": str(certs / f"{cert}.key"),
        "transport/auth/usrpwd/user": user, "transport/auth/usrpwd/password": password,
    }, drop=(f"{tls}/connect_certificate", f"{tls}/connect_private_key") if no_cert else ())


def test_operator_and_viewer_roles_with_mutual_tls(tmp_path: Path, daemons: Any,
                                                   agents: Any) -> None:
    users = make_certs(tmp_path)
    rogue = tmp_path / "rogue"  # the same recipe elsewhere: another CA
    make_certs(rogue)
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
        f"{tls}/connect_certificate": str(tmp_path / "pamd-daemon.pem"),
        f"{tls}/connect_private_key": str(tmp_path / "pamd-daemon.key"),
        "transport/auth/usrpwd/user": "rig-sim",
        "transport/auth/usrpwd/password": users["rig-sim"]})
    op_conf = client_conf(tmp_path, "operator-ana", "operator", "ana", users["ana"], port)
    view_conf = client_conf(tmp_path, "viewer-bob", "viewer", "bob", users["bob"], port)

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

        # wrong credentials do not connect at all, and the client says who refused, why
        for name, cert, user, pw, certs, no_cert, why in (
                ("rogue", "operator", "ana", users["ana"], rogue, False,  # another CA's
                 "the router at localhost:%d refuses this client's certificate"),
                ("nocert", "operator", "ana", users["ana"], None, True,  # no certificate
                 "the router at localhost:%d refuses this client's certificate (none given)"),
                ("wrongpw", "operator", "ana", "guess", None, False,  # wrong password
                 "TLS to localhost:%d works both ways")):
            conf = client_conf(tmp_path, name, cert, user, pw, port, certs, no_cert)
            bad = agents("--zenoh-config", str(conf))
            assert "cannot connect" in bad.hello.get("error", ""), (name, bad.hello)
            r = pamd_cli("status", "--zenoh-config", str(conf))
            assert r.returncode == 7 and why % port in r.stderr, (name, r.stderr)
        assert d.stop() == 0, d.log()[-3000:]
    finally:
        router.terminate()
        router.communicate(timeout=30)


def _resign(d: Path, name: str, ext: str | None) -> None:
    """Sign `name`'s request again: without extensions (X.509 v1, what the README's old
    recipe made) or with the extension file `ext`."""
    extra = ["-extfile", str(d / ext)] if ext else []
    subprocess.run(["openssl", "x509", "-req", "-in", str(d / f"{name}.csr"), "-CA",
                    str(d / "ca.pem"), "-CAkey", str(d / "ca.key"), "-CAcreateserial", "-out",
                    str(d / f"{name}.pem"), "-days", "2", *extra], check=True,
                   capture_output=True, timeout=60)


def _router(d: Path, port: int) -> subprocess.Popen[str]:
    tls = "transport/link/tls"
    conf = derive("lab-router.json5", d / "router.json5", {
        "listen/endpoints": [f"tls/127.0.0.1:{port}"],
        f"{tls}/root_ca_certificate": str(d / "ca.pem"),
        f"{tls}/listen_certificate": str(d / "router.pem"),
        f"{tls}/listen_private_key": str(d / "router.key"),
        "transport/auth/usrpwd/dictionary_file": str(d / "users.txt")})
    return subprocess.Popen([sys.executable, "-m", "pamd", "router", "--zenoh-config",
                             str(conf)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def test_a_tls_failure_says_which_side_refused_and_why(tmp_path: Path) -> None:
    users = make_certs(tmp_path)
    port = free_port()
    # a router whose own certificate is v1: it says so and does not start
    _resign(tmp_path, "router", None)
    router = _router(tmp_path, port)
    _, err = router.communicate(timeout=60)
    assert router.returncode != 0
    assert "refuses this side's own certificate" in err and "X.509 v1" in err, err

    # a router certificate without a subjectAltName: the client refuses it
    (tmp_path / "nosan.ext").write_text("basicConstraints=CA:FALSE\n")
    _resign(tmp_path, "router", "nosan.ext")
    router = _router(tmp_path, port)
    try:
        wait_listening(port)
        conf = client_conf(tmp_path, "op", "operator", "ana", users["ana"], port)
        r = pamd_cli("status", "--zenoh-config", str(conf))
        assert r.returncode == 7, r.stderr
        assert "this client refuses the router's certificate" in r.stderr
        assert "no subjectAltName" in r.stderr, r.stderr
    finally:
        router.terminate()
        router.communicate(timeout=30)

    # a good router, a client with a v1 certificate: the router would refuse it
    _resign(tmp_path, "router", "router.ext")
    _resign(tmp_path, "operator", None)
    router = _router(tmp_path, port)
    try:
        wait_listening(port)
        r = pamd_cli("status", "--zenoh-config", str(conf))
        assert r.returncode == 7, r.stderr
        assert "refuses this client's certificate" in r.stderr and "X.509 v1" in r.stderr
    finally:
        router.terminate()
        router.communicate(timeout=30)

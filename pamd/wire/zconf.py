"""Zenoh configs for the daemon, the CLI clients and the router, secure by default.

Zenoh's built-in defaults scout by UDP multicast and gossip, which leaves this
machine; every config built here turns both off unless the given file turns them on
explicitly, and names its endpoints. Without a file the daemon is a peer listening
on `telemetry.listen` only (default `tcp/127.0.0.1:7447`) and clients connect there.

Configs travel to the io process as JSON text (`str(zenoh.Config)`), checked here in
the daemon's main process so a bad file is refused before anything starts.

When a session does not open, `open_error` says why in words (in the process that
tried to open it), and for TLS which side refused and why. Zenoh only says "Unable
to connect" when a TLS handshake fails, and Zenoh's TLS (rustls) is stricter than
OpenSSL: it accepts only X.509 v3 certificates and matches the host a client connects
to against the server's subjectAltName, never its CN. So when a client's session does
not open on a `tls/` endpoint, `diagnose` tries the same connection once more with
Python's `ssl` (the same CA, certificate and key from the Zenoh config) and reads the
certificates itself:

- nothing listens: say so;
- the router's certificate is v1, names no subjectAltName or not the host, or does
  not verify against the CA: this client refuses it, and why;
- this client's certificate is v1, or the router ends the handshake with an alert
  (an unknown CA, no certificate sent): the router refuses it, and why;
- the handshake works both ways: TLS is fine, so the router refused the session
  itself (the user name and password of `transport/auth/usrpwd`).

`listen_error` does the same for a router whose own certificate Zenoh refuses.
Nothing here runs in the daemon's loop process; a probe is one connection with a
short timeout.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import ssl
from typing import TYPE_CHECKING, Protocol, TypeVar

from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.errors import ConfigError, ConfigIssue, PamdError

if TYPE_CHECKING:  # zenoh is imported where a session's config is built, never on import
    import zenoh

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
#: client sessions a daemon's own endpoint takes at once (each costs the io process
#: some 170 kB while connected): memory bounded, whatever clients do
MAX_SESSIONS = 100
#: the largest message a client may send it (Zenoh's default is 1 GiB, held whole in
#: the io process while it is reassembled); a command's JSON is refused above 64 KiB
#: anyway, and an estop or stop up to this size still acts
MAX_MESSAGE_BYTES = 4 << 20
# Zenoh's shared-memory transport stays off: with it, the first local subscriber made
# the io process map a 16 MiB pool it kept (+28 MB RSS for 50 clients, never returned)
SCOUTING_KEYS = ("scouting/multicast/enabled", "scouting/gossip/enabled")


class ZenohConfig(Protocol):
    """What is read and set here of a `zenoh.Config`."""

    def get_json(self, key: str) -> str: ...
    def insert_json5(self, key: str, value: str) -> object: ...


_Config = TypeVar("_Config", bound=ZenohConfig)


class NoDaemon(PamdError):
    """No daemon (or router) answers where the client looked."""

    exit_code = 7


def _issue(file: str, expected: str, found: str) -> ConfigError:
    return ConfigError([ConfigIssue(file, None, "", expected, found)])


def load_file(path: str) -> zenoh.Config:
    """A Zenoh config file (JSON5), checked by Zenoh itself."""
    import zenoh

    if not os.path.isfile(path):
        raise _issue(path, "a readable Zenoh config file (JSON5)", "no such file")
    try:
        cfg: zenoh.Config = zenoh.Config.from_file(path)
    except Exception as exc:  # zenoh.ZError: names the unknown or wrong field
        raise _issue(path, "a valid Zenoh config (JSON5)", str(exc).split(" at /")[0]) from None
    return cfg


def get(cfg: ZenohConfig, key: str) -> JsonValue:
    return json.loads(cfg.get_json(key))


def secure(cfg: _Config) -> _Config:
    """Multicast and gossip scouting off unless the config set them itself."""
    for key in SCOUTING_KEYS:
        if get(cfg, key) is None:
            cfg.insert_json5(key, "false")
    return cfg


def endpoints(cfg: ZenohConfig, which: str) -> list[str]:
    eps = get(cfg, f"{which}/endpoints")
    if isinstance(eps, dict):  # per-mode endpoints: {router: [...], peer: [...], ...}
        eps = eps.get(get(cfg, "mode") or "peer") or []
    return [str(e) for e in eps or []]


def daemon_config(file: str | None, listen: str = DEFAULT_LISTEN,
                  max_sessions: int = MAX_SESSIONS) -> zenoh.Config:
    """The daemon's session: the file as given, or a peer listening on `listen` that
    takes at most `max_sessions` client sessions at once, messages of at most
    MAX_MESSAGE_BYTES, and no shared-memory transport."""
    import zenoh

    if file is not None:
        cfg = load_file(file)
    else:
        cfg = zenoh.Config.from_json5(json.dumps(
            {"mode": "peer", "listen": {"endpoints": [listen]},
             "connect": {"endpoints": []},
             "transport": {"unicast": {"max_sessions": max_sessions},
                           "link": {"rx": {"max_message_size": MAX_MESSAGE_BYTES}},
                           "shared_memory": {"enabled": False}}}))
    return secure(cfg)


#: link protocols that encrypt (Zenoh's TLS and QUIC); the others carry commands,
#: state and status in clear
ENCRYPTED = ("tls", "quic")
#: link protocols that never leave the machine
LOCAL_ONLY = ("unixsock-stream", "unixpipe", "vsock")


def host_of(endpoint: str) -> tuple[str, str, str]:
    """(protocol, host, port) of `proto/host:port[#...]`."""
    proto, _, addr = endpoint.partition("/")
    addr = addr.split("#", 1)[0].split("?", 1)[0]
    host, _, port = addr.rpartition(":")
    return proto, host.strip("[]"), port


def is_loopback_host(host: str) -> bool:
    """Whether `host` (an address or name, IPv6 with or without brackets) is this
    machine's loopback (127.0.0.0/8, ::1, localhost); "" (no host), 0.0.0.0 and :: are
    every interface, a LAN address or another name another machine (pamd.wire.cleartext
    judges every link by it)."""
    host = host.strip("[]").lower()
    return host == "localhost" or host == "::1" or host.startswith("127.")


def is_loopback(endpoint: str) -> bool:
    """Whether an endpoint's host is this machine's loopback (127.0.0.0/8, ::1,
    localhost); 0.0.0.0 and [::] are every interface, not loopback."""
    proto, host, _ = host_of(endpoint)
    return proto in LOCAL_ONLY or is_loopback_host(host)


def same_endpoint(listen: str, connect: str) -> bool:
    """Whether a client connecting to `connect` reaches a session listening on `listen`
    (same protocol and port; the listen host this machine's, any or loopback)."""
    lp, lh, lport = host_of(listen)
    cp, _ch, cport = host_of(connect)
    return lp == cp and lport == cport and (lh in ("0.0.0.0", "::", "") or is_loopback(listen))


def cleartext_beyond_loopback(cfg: ZenohConfig, which: str = "listen") -> list[str]:
    """The `which` ("listen" or "connect") endpoints whose far end can be another
    machine, without TLS (plain tcp, udp, ws on 0.0.0.0, a LAN address or a host name):
    what travels there, commands included, can be read on the way (pamd.wire.cleartext)."""
    return [e for e in endpoints(cfg, which)
            if not is_loopback(e) and host_of(e)[0] not in ENCRYPTED]


def endpoint_line(path: str, endpoint: str) -> int | None:
    """The line of a Zenoh config file that names `endpoint` (None if none does)."""
    with contextlib.suppress(OSError, UnicodeDecodeError), open(path, encoding="utf-8") as fh:
        for i, line in enumerate(fh, 1):
            if endpoint in line:
                return i
    return None


def _connect_for(listen: str) -> str:
    """A listen endpoint as a client reaches it on the same host."""
    proto, _, addr = listen.partition("/")
    addr = addr.split("#", 1)[0]
    host, _, port = addr.rpartition(":")
    if host in ("0.0.0.0", ""):
        host = "127.0.0.1"
    elif host in ("[::]", "::"):
        host = "[::1]"
    return f"{proto}/{host}:{port}"


def client_config(file: str | None = None, connect: str | None = None) -> zenoh.Config:
    """A CLI client's session: client mode, connecting to `connect`, to the file's
    connect endpoints, or (a daemon's file, with listen endpoints only) to where that
    daemon listens; with neither, to the default `tcp/127.0.0.1:7447`."""
    import zenoh

    if file is None:
        cfg: zenoh.Config = zenoh.Config.from_json5(json.dumps(
            {"mode": "client", "connect": {"endpoints": [connect or DEFAULT_LISTEN]}}))
        return secure(cfg)
    cfg = load_file(file)
    if connect is not None:
        eps = [connect]
    else:
        eps = endpoints(cfg, "connect") or [_connect_for(e) for e in endpoints(cfg, "listen")]
    if not eps:
        raise _issue(file, "connect or listen endpoints to reach the daemon or router",
                     "neither")
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps(eps))
    cfg.insert_json5("listen/endpoints", "[]")
    return secure(cfg)


def router_config(file: str) -> zenoh.Config:
    """`pamd router`: the file, in router mode, with endpoints to listen on."""
    cfg = load_file(file)
    mode = get(cfg, "mode")
    if mode not in (None, "router"):
        raise _issue(file, "mode: \"router\" (or no mode)", f"mode {mode!r}")
    cfg.insert_json5("mode", '"router"')
    if not endpoints(cfg, "listen"):
        raise _issue(file, "listen endpoints (e.g. tls/0.0.0.0:7447)", "none")
    return secure(cfg)


def open_error(exc: BaseException, cfg: ZenohConfig) -> str:
    """What an operator needs to read when a session does not open."""
    text = str(exc).split(" at /")[0]
    if "Address already in use" in text or "address in use" in text.lower():
        eps = ", ".join(endpoints(cfg, "listen")) or "its endpoint"
        return (f"cannot listen on {eps}: the address is in use (another pamd or Zenoh "
                "router?); set telemetry.listen or telemetry.zenoh_config, or run with "
                "--no-telemetry")
    if "Unable to connect" in text:
        eps = ", ".join(endpoints(cfg, "connect")) or "its endpoints"
        why = _tls_why(cfg)
        if why:
            return f"cannot connect to {eps}: {why}"
        return f"cannot connect to {eps} (nothing listening, or refused: TLS/credentials?)"

    return listen_error(text, get(cfg, "transport/link/tls/listen_certificate")) or text


def _tls_why(cfg: ZenohConfig) -> str | None:
    """Which side refused a `tls/` connection and why (`diagnose`, below)."""

    tls = [e for e in endpoints(cfg, "connect") if e.startswith("tls/")]
    if not tls:
        return None
    path = "transport/link/tls/"
    return "; ".join(diagnose(e, get(cfg, path + "root_ca_certificate"),
                              get(cfg, path + "connect_certificate"),
                              get(cfg, path + "connect_private_key")) for e in tls)


# -- why a TLS session did not open -----------------------------------------------------
#: rustls' certificate errors (as Zenoh's messages name them) in an operator's words
RUSTLS_REASONS = {
    "UnsupportedCertVersion": "it is an X.509 v1 certificate; Zenoh accepts only v3 (make "
                              "it with `-extfile`, as docs/how-to/lab-network.md's openssl "
                              "recipe does)",
    "NotValidForName": "its subjectAltName does not name the host the client connects to",
    "UnknownIssuer": "it is not signed by the CA in root_ca_certificate",
    "Expired": "it has expired",
    "NotValidYet": "it is not valid yet (check the clocks)",
    "CaUsedAsEndEntity": "it is a CA certificate, used as a server or client certificate",
    "BadEncoding": "it is not a readable certificate",
}

_SAN_OID = bytes.fromhex("0603551d11")  # OBJECT IDENTIFIER 2.5.29.17 (subjectAltName)


def explain_rustls(text: str) -> str | None:
    """The reason rustls gave in a Zenoh error message, in words (None if none)."""
    for key, words in RUSTLS_REASONS.items():
        if key in text:
            return words
    return None


def listen_error(text: str, cert_file: str | None) -> str | None:
    """A router (or listening daemon) whose own certificate Zenoh refused."""
    reason = explain_rustls(text)
    if reason is None or "listener" not in text.lower():
        return None
    return f"Zenoh refuses this side's own certificate {cert_file or '(listen_certificate)'}: " \
           f"{reason}"


# -- a minimal DER reader: enough for a certificate's version and extensions -------------
def _tlv(data: bytes, pos: int) -> tuple[int, int, int]:
    """(tag, start of content, end of content) of the DER element at `pos`."""
    tag = data[pos]
    length = data[pos + 1]
    pos += 2
    if length & 0x80:
        n = length & 0x7F
        length = int.from_bytes(data[pos:pos + n], "big")
        pos += n
    return tag, pos, pos + length


def cert_facts(der: bytes) -> tuple[int, bool]:
    """(X.509 version 1-3, has a subjectAltName) of a DER certificate."""
    _, cert, _ = _tlv(der, 0)  # Certificate ::= SEQUENCE { tbsCertificate, ... }
    _, tbs, tbs_end = _tlv(der, cert)
    tag, vstart, vend = _tlv(der, tbs)
    version = 1
    if tag == 0xA0:  # [0] EXPLICIT Version (absent means v1)
        _, istart, iend = _tlv(der, vstart)
        version = int.from_bytes(der[istart:iend], "big") + 1
    return version, _SAN_OID in der[tbs:tbs_end]


def _pem_certs(path: str) -> list[bytes]:
    with open(path, encoding="ascii", errors="replace") as fh:
        text = fh.read()
    out = []
    for block in text.split("-----BEGIN CERTIFICATE-----")[1:]:
        body = block.split("-----END CERTIFICATE-----")[0]
        out.append(ssl.PEM_cert_to_DER_cert(
            "-----BEGIN CERTIFICATE-----" + body + "-----END CERTIFICATE-----\n"))
    return out


def _host_port(endpoint: str) -> tuple[str, int]:
    addr = endpoint.partition("/")[2].split("#", 1)[0]
    host, _, port = addr.rpartition(":")
    return host.strip("[]"), int(port)


def diagnose(endpoint: str, ca: str | None, cert: str | None, key: str | None,
             timeout_s: float = 3.0) -> str:
    """Which side refused a TLS connection to `endpoint` (`tls/host:port`), and why."""
    host, port = _host_port(endpoint)
    where = f"{host}:{port}"
    if cert:
        with contextlib.suppress(OSError, ValueError, IndexError):
            ours = _pem_certs(cert)
            if ours and cert_facts(ours[0])[0] < 3:
                return (f"the router at {where} refuses this client's certificate {cert}: "
                        f"{RUSTLS_REASONS['UnsupportedCertVersion']}")
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as exc:
        return f"nothing accepts connections at {where} ({exc.strerror or exc}): is the " \
               "router running, and is this its address?"
    with sock:
        # First without checking, to read the router's certificate as rustls would.
        peek = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
        peek.check_hostname, peek.verify_mode = False, ssl.CERT_NONE
        _load_own(peek, cert, key)
        try:
            with peek.wrap_socket(sock, server_hostname=host) as tls:
                der = tls.getpeercert(binary_form=True)
        except (ssl.SSLError, OSError) as exc:
            return f"the TLS handshake with {where} failed: {_ssl_reason(exc)}"
    if der:
        version, has_san = cert_facts(der)
        if version < 3:
            return (f"this client refuses the router's certificate ({where}): "
                    f"{RUSTLS_REASONS['UnsupportedCertVersion']}")
        if not has_san:
            return (f"this client refuses the router's certificate ({where}): it has no "
                    f"subjectAltName; Zenoh checks the host ({host}) against it, never the CN")
    return _verify(host, port, ca, cert, key, timeout_s)


def _load_own(ctx: ssl.SSLContext, cert: str | None, key: str | None) -> None:
    if cert and key:
        with contextlib.suppress(OSError, ssl.SSLError):
            ctx.load_cert_chain(cert, key)


def _verify(host: str, port: int, ca: str | None, cert: str | None, key: str | None,
            timeout_s: float) -> str:
    """The full check, as Zenoh does it: the router's certificate against the CA and
    the host; then whether the router accepts this client's certificate."""
    where = f"{host}:{port}"
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    try:
        if ca:
            ctx.load_verify_locations(ca)
        else:
            ctx.load_default_certs()
    except (OSError, ssl.SSLError) as exc:
        return f"this client cannot read its CA file {ca}: {_ssl_reason(exc)}"
    _load_own(ctx, cert, key)
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as sock, \
                ctx.wrap_socket(sock, server_hostname=host) as tls:
            # TLS 1.3: the router judges the client's certificate after the handshake;
            # its verdict is an alert on the first read (or nothing, or its greeting).
            tls.settimeout(min(timeout_s, 1.0))
            with contextlib.suppress(TimeoutError, socket.timeout):
                tls.recv(1)
    except ssl.SSLCertVerificationError as exc:
        return (f"this client refuses the router's certificate ({where}): "
                f"{exc.verify_message or _ssl_reason(exc)}")
    except ssl.SSLError as exc:
        return (f"the router at {where} refuses this client's certificate "
                f"{cert or '(none given)'}: {_ssl_reason(exc)}")
    except OSError:
        pass  # the router closed an idle, unauthenticated link: TLS itself was accepted
    return (f"TLS to {where} works both ways (the router accepts this client's certificate "
            "and this client the router's), so the router refused the session itself: "
            "check transport/auth/usrpwd (user and password in the router's dictionary "
            "file)")


def _ssl_reason(exc: BaseException) -> str:
    if isinstance(exc, ssl.SSLError) and exc.reason:
        reason = exc.reason.lower().replace("_", " ")
        hints = {"alert certificate required": "the router wants a client certificate "
                 "(connect_certificate and connect_private_key)",
                 "alert unknown ca": "the router does not know the CA that signed it",
                 "alert bad certificate": "the router rejected it",
                 "alert unsupported certificate": "the router cannot use it (X.509 v3?)"}
        for k, v in hints.items():
            if k in reason:
                return f"{reason}: {v}"
        return reason
    return str(exc)

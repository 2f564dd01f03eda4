"""Why a TLS session did not open, in words: which side refused and why.

Zenoh only says "Unable to connect" when a TLS handshake fails, and Zenoh's TLS
(rustls) is stricter than OpenSSL: it accepts only X.509 v3 certificates and
matches the host a client connects to against the server's subjectAltName, never
its CN. So when a client's session does not open on a `tls/` endpoint, `diagnose`
tries the same connection once more with Python's `ssl` (the same CA, certificate
and key from the Zenoh config) and reads the certificates itself:

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
import socket
import ssl

#: rustls' certificate errors (as Zenoh's messages name them) in an operator's words
RUSTLS_REASONS = {
    "UnsupportedCertVersion": "it is an X.509 v1 certificate; Zenoh accepts only v3 (make "
                              "it with `-extfile`, as the README's openssl recipe does)",
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

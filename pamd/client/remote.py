"""The client side: a Zenoh session in client mode that finds rigs (liveliness),
asks for status, sends commands and subscribes to state. Used by the CLI (`pamd
status`, `pamd cmd`, `pamd watch`), the tests and the benchmarks; a lab script can
use it too, or talk to the key space with any Zenoh client.

Each command query declares this session's Zenoh id (`source_info`) and the user
(`?user=NAME`); the daemon records both but authenticates neither. What it checks is
the command's signature, made with the daemon's token (found as
`pamd.wire.credential.find_token` says) over the command, a counter and the daemon's
run nonce (its status says it; asked once per rig): the token itself never travels
(on a lab network the router's access control decides, besides, who reaches the
daemon at all: config/zenoh/lab-router.json5). An estop or stop too large is cut here
before it goes (`command_body`).

A client's session ends with it (closed, or collected), and when its daemon or router
goes away: it is closed then rather than left to reconnect by itself to the next
daemon on that endpoint (whose session cap idle sessions filled); the next call opens
a new one.

Rig ids are names, never key patterns: `*`, `**`, `$*`, `?` or `/` in a rig id is
refused here before anything is sent (a pattern reached every daemon of a lab). A
read-only subscription may take a pattern, named as such (`subscribe_pattern`).
"""

from __future__ import annotations

import contextlib
import getpass
import itertools
import json
import re
import threading
import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from pamd.config.names import CHUNK_RE
from pamd.iohost.intake import ESTOP, MAX_PAYLOAD_BYTES, salvage, salvage_object
from pamd.wire import zconf
from pamd.wire.credential import BAD, STALE, Signer, find_token
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import PamdError
from pamd.wire.keys import ROOT, Keys
from pamd.wire.local_channel import LocalClient, socket_paths
from pamd.wire.verbs.table import VERBS
from pamd.wire.zconf import NoDaemon

if TYPE_CHECKING:  # zenoh is imported when a client opens its session, never on import
    import zenoh
    from zenoh.handlers import Handler

DEFAULT_TIMEOUT_S = 3.0


class BadRigName(PamdError):
    """A rig id that is not a name (a key pattern, or not a key chunk at all)."""

    exit_code = 2


def rig_name(rig: str) -> str:
    """`rig` if it is a rig's name; BadRigName (saying why) if not."""
    if CHUNK_RE.match(rig):
        return rig
    shown = rig if len(rig) <= 80 else rig[:80] + "..."
    raise BadRigName(f"rig {shown!r} is not a rig's name: a rig id is letters, digits, "
                     "'_', '-' and '.', never a pattern ('*', '**', '$*'): a command "
                     "goes to one rig, named (`pamd status` with no --rig lists them)")


class Client:
    def __init__(self, zenoh_config: str | None = None, connect: str | None = None,
                 token_file: str | None = None) -> None:
        """`token_file`: the command credential's file (default: as
        `pamd.wire.credential.find_token` finds it for the rig)."""
        import zenoh

        self.zenoh = zenoh
        cfg = zconf.client_config(zenoh_config, connect)
        self.where = ", ".join(zconf.endpoints(cfg, "connect")) or "?"
        self._config = str(cfg)  # a session's config is spent on it: kept as text
        self._session: zenoh.Session | None = None
        self._closed = False
        self.lost = False  # the daemon (or router) went away: the session was closed
        self._sn = itertools.count(1)
        self.token_file = token_file
        self._signers: dict[str, Signer] = {}  # per rig: the token's, with its counter
        self._nonces: dict[str, str] = {}  # per rig: the daemon's run nonce, as last seen
        self._opened = itertools.count(1)
        self._n_open = 0
        self._open()

    def _open(self) -> zenoh.Session:
        """A session to the daemon or router, watched: when its last transport closes,
        the session is closed at once (`lose`) rather than left to reconnect by itself
        to whatever listens there next, such as the next daemon, whose session cap it
        would fill while nobody uses it. The next call opens a new one."""
        z = self.zenoh
        cfg = z.Config.from_json5(self._config)
        try:
            s: zenoh.Session = z.open(cfg)
        except Exception as exc:
            raise NoDaemon(f"no daemon or router to talk to: {zconf.open_error(exc, cfg)}"
                           ) from None
        # the listener holds neither the client nor the session (its callback lives as
        # long as the session: either would keep the session open after its owner went)
        ref, opened = weakref.ref(self), next(self._opened)

        def on_transport(event: zenoh.TransportEvent) -> None:
            client = ref()
            if client is not None and event.kind == z.SampleKind.DELETE:
                client.lose(opened)

        self._watch = s.info.declare_transport_events_listener(on_transport)
        self._session, self._n_open, self.lost = s, opened, False
        return s

    def lose(self, opened: int) -> None:
        """Zenoh's callback thread: the link to the daemon or router closed. Its session
        is closed on a thread of its own (never inside its own callback)."""
        s = self._session
        if self._closed or s is None or opened != self._n_open:
            return  # closed by its owner, or an older session
        self._session, self.lost = None, True
        threading.Thread(target=_close_quietly, args=(s,), name="pamd-client-lost",
                         daemon=True).start()

    @property
    def session(self) -> zenoh.Session:
        """The session, opened again if the daemon went away since (NoDaemon if none
        answers now)."""
        s = self._session
        if s is None:
            if self._closed:
                raise NoDaemon("this client was closed")
            s = self._open()
        return s

    def close(self) -> None:
        self._closed = True
        s, self._session = self._session, None
        if s is not None:
            s.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- finding rigs ----------------------------------------------------------------------
    def rigs(self, timeout_s: float = 1.5) -> list[str]:
        """Rig ids whose daemon's liveliness token is up."""
        found = set()
        for r in self.session.liveliness().get(f"{ROOT}/*/alive", timeout=timeout_s):
            if r.ok is not None:
                found.add(Keys.rig_of(str(r.ok.key_expr)))
        return sorted(found)

    def rig(self, rig: str | None, timeout_s: float = 1.5) -> str:
        """`rig` itself (a name: BadRigName if a pattern), or the one rig alive;
        NoDaemon if none, or several (it lists them)."""
        if rig is not None:
            return rig_name(rig)
        rigs = self.rigs(timeout_s)
        if not rigs:
            raise NoDaemon(f"no pamd daemon is alive via {self.where} (none declares "
                           f"{ROOT}/<rig>/alive; is pamd running with telemetry on?)")
        if len(rigs) > 1:
            raise NoDaemon(f"several rigs answer via {self.where}: {', '.join(rigs)}; name "
                           "one with --rig (pamd.connect(rig=...))")
        return rigs[0]

    # -- queries ----------------------------------------------------------------------------
    def _kw(self, timeout_s: float, payload: bytes | None, attachment: bytes | None,
            urgent: bool, block: bool = False
            ) -> dict[str, Any]:  # Any: zenoh's option objects, for Session.get(**kw)
        """`urgent` (an estop or stop): never dropped on the way, at the highest priority
        (its payload cut to fit first: `command_body`); `block`: never dropped either."""
        z = self.zenoh
        # Any: zenoh's own option objects of several types, for Session.get(**kw)
        kw: dict[str, Any] = {"timeout": timeout_s, "congestion_control": (
            z.CongestionControl.BLOCK if urgent or block else z.CongestionControl.DROP)}
        if urgent:
            kw["priority"] = z.Priority.REAL_TIME
        if payload is not None:
            kw.update(payload=payload, encoding=z.Encoding.APPLICATION_JSON,
                      source_info=z.SourceInfo(self.session.id, next(self._sn)))
        if attachment is not None:
            kw["attachment"] = attachment
        return kw

    def _get(self, selector: str, payload: bytes | None, timeout_s: float,
             attachment: bytes | None = None, urgent: bool = False) -> JsonObject:
        kw = self._kw(timeout_s, payload, attachment, urgent)
        for r in self.session.get(selector, **kw):
            if r.ok is not None:
                try:
                    answer: JsonObject = json.loads(r.ok.payload.to_bytes())
                    return answer
                except ValueError:
                    return {"ok": False, "error": "the reply is not JSON: "
                            + r.ok.payload.to_bytes()[:200].decode("utf-8", "replace")}
            if r.err is not None:
                error = r.err.payload.to_bytes().decode("utf-8", "replace")
                if error == "Timeout":  # zenoh's own reply when the query's time ran out
                    error = (f"no answer within {timeout_s:g} s: the command may not have "
                             "reached the daemon (on a congested link this client drops "
                             "any command but an estop or stop, which it cuts to fit and "
                             "holds until sent) or was answered too late; check the rig's "
                             "status before sending it again")
                return {"ok": False, "error": error}
        raise self._no_answer(selector.split("?", 1)[0], timeout_s)

    def _no_answer(self, key: str, timeout_s: float) -> NoDaemon:
        return NoDaemon(f"no answer on {key} within {timeout_s:g} s via {self.where} (no "
                        "daemon for that rig, telemetry off, or not allowed: a viewer "
                        "cannot command)")

    def status(self, rig: str, timeout_s: float = DEFAULT_TIMEOUT_S) -> JsonObject:
        st = self._get(Keys(rig_name(rig)).status, None, timeout_s)
        nonce = st.get("command_nonce")
        if isinstance(nonce, str):
            self._nonces[rig] = nonce
        return st

    def _signer(self, rig: str) -> tuple[Signer | None, str]:
        """The rig's token as a signer (None if no token is found) and where it was."""
        signer = self._signers.get(rig)
        if signer is not None:
            return signer, ""
        token, where = find_token(rig, self.token_file)
        if token is None:
            return None, where
        signer = self._signers[rig] = Signer(token)
        return signer, where

    def _nonce(self, rig: str, timeout_s: float) -> str | None:
        """The daemon's run nonce (its status says it), as last seen."""
        if rig not in self._nonces:
            self.status(rig, min(timeout_s, DEFAULT_TIMEOUT_S))
        return self._nonces.get(rig)

    def _attachment(self, rig: str, verb: str, body: bytes, timeout_s: float
                    ) -> tuple[bytes | None, str]:
        """The command's signature (pamd.wire.credential), and where the token was looked
        for when none was found. An estop goes at once: unsigned when this client has not
        seen the daemon's nonce yet (anyone may stop the rig; it is recorded as sent
        without a credential), never waiting for a status first."""
        signer, where = self._signer(rig)
        if signer is None:
            return None, where
        if verb == ESTOP and rig not in self._nonces:
            return None, where
        nonce = self._nonce(rig, timeout_s)
        if nonce is None:
            return None, where
        return signer.attachment(rig, verb, body, nonce), where

    def command(self, rig: str, verb: str, payload: JsonObject | str | bytes | None = None,
                user: str | None = None, timeout_s: float = 10.0) -> JsonObject:
        """Send a command to rig `rig` (a name), signed with the rig's credential; the
        reply is the loop's verdict (or the io process's refusal). A str/bytes payload is
        sent as is (malformed JSON too), but an estop's or stop's is cut first to what
        the daemon takes (`urgent_body`)."""
        rig = rig_name(rig)
        body, note = command_body(verb, payload)
        sel = Keys(rig).cmd(verb) + selector_user(user)
        urgent = VERBS.is_urgent(verb)
        if not urgent and len(body) > zconf.MAX_MESSAGE_BYTES:
            return {"ok": False, "error": f"{verb}: payload of {len(body)} bytes, above the "
                    f"daemon's limit of {MAX_PAYLOAD_BYTES} bytes; not sent"}
        try:
            att, where = self._attachment(rig, verb, body, timeout_s)
        except NoDaemon:  # its status did not answer: neither would the command
            raise self._no_answer(Keys(rig).cmd(verb), timeout_s) from None
        verdict = self._get(sel, body, timeout_s, att, urgent)
        if att is not None and self._renew(rig, verdict):  # signed again, once
            att, where = self._attachment(rig, verb, body, timeout_s)
            verdict = self._get(sel, body, timeout_s, att, urgent)
        if att is None and "credential" in str(verdict.get("error", "")):
            verdict["error"] = f"{verdict['error']} (no token found: looked in {where})"
        if note:
            verdict.setdefault("cut", note)
        return verdict

    def _renew(self, rig: str, verdict: JsonObject) -> bool:
        """Whether a refusal of this client's signature is worth one more try: the daemon
        restarted (its new nonce taken), or the token was rotated (the file read again:
        `pamd token --rotate`)."""
        why = verdict.get("credential")
        if why == STALE and isinstance(nonce := verdict.get("command_nonce"), str):
            self._nonces[rig] = nonce
            return True
        if why == BAD and rig in self._signers:
            old = self._signers.pop(rig).key
            signer, _ = self._signer(rig)
            return signer is not None and signer.key != old
        return False

    def send(self, rig: str, verb: str, body: bytes,
             on_reply: Callable[[zenoh.Reply], None], timeout_s: float = 10.0) -> None:
        """A command sent without waiting for its answer (signed as `command` signs;
        `on_reply` gets Zenoh's reply on its callback thread; held back, never dropped,
        on a congested link): for loads and scripts that stream."""
        rig = rig_name(rig)
        att, _ = self._attachment(rig, verb, body, timeout_s)
        kw = self._kw(timeout_s, body, att, VERBS.is_urgent(verb), block=True)
        self.session.get(Keys(rig).cmd(verb), on_reply, **kw)

    def subscribe(self, key: str, capacity: int = 4096
                  ) -> zenoh.Subscriber[Handler[zenoh.Sample]]:
        """A subscriber with a ring channel (`try_recv`, no callback thread) to `key` of
        one rig: its rig chunk must be a name (BadRigName if a pattern)."""
        rig_name(Keys.rig_of(key))
        return self.subscribe_pattern(key, capacity)

    def subscribe_pattern(self, pattern: str, capacity: int = 4096
                          ) -> zenoh.Subscriber[Handler[zenoh.Sample]]:
        """A read-only subscription that may span rigs (`pamd/*/events`): named as a
        pattern, for watching; commands never take one."""
        return self.session.declare_subscriber(pattern,
                                               self.zenoh.handlers.RingChannel(capacity))


def _close_quietly(s: zenoh.Session) -> None:
    with contextlib.suppress(Exception):
        s.close()


#: an estop's or stop's payload larger than this is cut by the client before it goes
#: (the daemon takes only its declared fields, text capped at MAX_TEXT_CHARS)
URGENT_CUT_BYTES = 4096


def command_body(verb: str, payload: JsonObject | str | bytes | None) -> tuple[bytes, str]:
    """The bytes a command sends, and what was cut of an estop's or stop's ("" if
    nothing): one larger than URGENT_CUT_BYTES is cut here to its declared fields, text
    capped (`salvage`, as the daemon would), so it always fits a message the daemon
    takes and acts at once (an estop of 4 MiB was dropped on the way)."""
    if payload is None:
        body = b"{}"
    elif isinstance(payload, bytes):
        body = payload
    elif isinstance(payload, str):
        body = payload.encode()
    else:
        body = json.dumps(payload).encode()  # NaN and Infinity go out as such
    if not VERBS.is_urgent(verb) or len(body) <= URGENT_CUT_BYTES:
        return body, ""
    kept, note = (salvage_object(verb, payload) if isinstance(payload, dict)
                  else salvage(verb, body))
    return json.dumps(kept).encode(), note


def selector_user(user: str | None) -> str:
    """`?user=NAME` (the login if None): one selector parameter, nothing more."""
    if user is None:
        try:
            user = getpass.getuser()
        except (KeyError, OSError):
            user = ""
    user = re.sub(r"[^\w.@-]", "_", user)
    return f"?user={user}" if user else ""


# -- the local channel (pamd.wire.local_channel): the rig PC's way in, outside Zenoh -------------
class LocalRig:
    """A daemon's local channel in the shape `pamd status` and `pamd cmd` use of a
    `Client` (`rig`, `status`, `command`): its commands need no signature (the kernel
    names the sender, and only the token's readers reach the socket)."""

    def __init__(self, conn: LocalClient, hello: JsonObject) -> None:
        self.conn = conn
        self.name = str(hello.get("rig"))
        self.where = f"the local channel {conn.path}"

    def rig(self, rig: str | None, timeout_s: float = 1.5) -> str:
        if rig is not None and rig_name(rig) != self.name:
            raise NoDaemon(f"{self.where} is rig {self.name!r}'s, not {rig!r}")
        return self.name

    def status(self, rig: str, timeout_s: float = DEFAULT_TIMEOUT_S) -> JsonObject:
        return self.conn.status(timeout_s)

    def command(self, rig: str, verb: str, payload: JsonObject | str | bytes | None = None,
                user: str | None = None, timeout_s: float = 10.0) -> JsonObject:
        body, note = command_body(verb, payload)
        verdict = self.conn.command(verb, body, selector_user(user).removeprefix("?user="),
                                    timeout_s)
        if note:
            verdict.setdefault("cut", note)
        return verdict

    def close(self) -> None:
        self.conn.close()

    def __enter__(self) -> LocalRig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def local_rig(rig: str | None, connect: str | None = None) -> LocalRig | None:
    """The local channel of `rig`'s daemon on this machine (None: of the one rig that
    has one), of the daemon listening on `connect` when that is named (a loopback
    endpoint: a client that names a port means that daemon); None if there is none."""
    if connect is not None and not zconf.is_loopback(connect):
        return None
    found: list[LocalRig] = []
    for path in socket_paths(None if rig is None else rig_name(rig)):
        try:
            conn = LocalClient(path, 1.0)
        except NoDaemon:
            continue
        try:
            hello = conn.hello()
        except (NoDaemon, ValueError):
            conn.close()
            continue
        listen = hello.get("listen")
        eps = [str(e) for e in listen] if isinstance(listen, list) else []
        if connect is None or any(zconf.same_endpoint(e, connect) for e in eps):
            found.append(LocalRig(conn, hello))
        else:
            conn.close()
    if len(found) == 1:
        return found[0]
    for f in found:
        f.close()
    return None

"""The client side: a Zenoh session in client mode that finds rigs (liveliness),
asks for status, sends commands and subscribes to state. Used by the CLI (`pamd
status`, `pamd cmd`, `pamd watch`), the tests and the benchmarks; a lab script can
use it too, or talk to the key space with any Zenoh client.

Each command query declares this session's Zenoh id (`source_info`) and the user
(`?user=NAME`); the daemon records both but authenticates neither. What it checks is
the command credential, the daemon's token, carried in the query's attachment and
found as `pamd.net.credential.find_token` says (on a lab network the router's access
control decides, besides, who reaches the daemon at all: config/zenoh/lab-router.json5).

Rig ids are names, never key patterns: `*`, `**`, `$*`, `?` or `/` in a rig id is
refused here before anything is sent (a pattern reached every daemon of a lab). A
read-only subscription may take a pattern, named as such (`subscribe_pattern`).
"""

from __future__ import annotations

import getpass
import itertools
import json
import re
from typing import TYPE_CHECKING, Any

from pamd.config.names import CHUNK_RE
from pamd.declare.jsonsafe import JsonObject
from pamd.errors import PamdError
from pamd.net import zconf
from pamd.net.credential import attachment, find_token
from pamd.net.keys import ROOT, Keys
from pamd.net.zconf import NoDaemon
from pamd.verbs.table import VERBS

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
        `pamd.net.credential.find_token` finds it for the rig)."""
        import zenoh

        self.zenoh = zenoh
        cfg = zconf.client_config(zenoh_config, connect)
        self.where = ", ".join(zconf.endpoints(cfg, "connect")) or "?"
        try:
            self.session = zenoh.open(cfg)
        except Exception as exc:
            raise NoDaemon(f"no daemon or router to talk to: {zconf.open_error(exc, cfg)}"
                           ) from None
        self._sn = itertools.count(1)
        self.token_file = token_file

    def close(self) -> None:
        self.session.close()

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
    def _get(self, selector: str, payload: bytes | None, timeout_s: float,
             token: str | None = None, urgent: bool = False) -> JsonObject:
        """`urgent` (an estop or stop): never dropped on the way (a large one goes in
        fragments, which the drop policy may lose), at the highest priority."""
        z = self.zenoh
        # Any: zenoh's own option objects of several types, for Session.get(**kw)
        kw: dict[str, Any] = {"timeout": timeout_s, "congestion_control": (
            z.CongestionControl.BLOCK if urgent else z.CongestionControl.DROP)}
        if urgent:
            kw["priority"] = z.Priority.REAL_TIME
        if payload is not None:
            kw.update(payload=payload, encoding=z.Encoding.APPLICATION_JSON,
                      source_info=z.SourceInfo(self.session.id, next(self._sn)))
        if token is not None:
            kw["attachment"] = attachment(token)
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
                    error = (f"no answer within {timeout_s:g} s: the command may have been "
                             "dropped on a congested link (only estop and stop are never "
                             "dropped) or answered too late; check the rig's status before "
                             "sending it again")
                return {"ok": False, "error": error}
        key = selector.split("?", 1)[0]
        raise NoDaemon(f"no answer on {key} within {timeout_s:g} s via {self.where} (no "
                       "daemon for that rig, telemetry off, or not allowed: a viewer "
                       "cannot command)")

    def status(self, rig: str, timeout_s: float = DEFAULT_TIMEOUT_S) -> JsonObject:
        return self._get(Keys(rig_name(rig)).status, None, timeout_s)

    def command(self, rig: str, verb: str, payload: JsonObject | str | bytes | None = None,
                user: str | None = None, timeout_s: float = 10.0) -> JsonObject:
        """Send a command to rig `rig` (a name) with the rig's credential; the reply
        is the loop's verdict (or the io process's refusal). A str/bytes payload is
        sent as is (malformed JSON too)."""
        rig = rig_name(rig)
        if payload is None:
            body = b"{}"
        elif isinstance(payload, bytes):
            body = payload
        elif isinstance(payload, str):
            body = payload.encode()
        else:
            body = json.dumps(payload).encode()  # NaN and Infinity go out as such
        if user is None:
            try:
                user = getpass.getuser()
            except (KeyError, OSError):
                user = ""
        user = re.sub(r"[^\w.@-]", "_", user)  # one selector parameter, nothing more
        sel = Keys(rig).cmd(verb) + (f"?user={user}" if user else "")
        token, where = find_token(rig, self.token_file)
        verdict = self._get(sel, body, timeout_s, token, VERBS.is_urgent(verb))
        if token is None and "credential" in str(verdict.get("error", "")):
            verdict["error"] = f"{verdict['error']} (no token found: looked in {where})"
        return verdict

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

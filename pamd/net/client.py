"""The client side: a Zenoh session in client mode that finds rigs (liveliness),
asks for status, sends commands and subscribes to state. Used by the CLI (`pamd
status`, `pamd cmd`, `pamd watch`), the tests and the benchmarks; a lab script can
use it too, or talk to the key space with any Zenoh client.

Each command query declares this session's Zenoh id (`source_info`) and the user
(`?user=NAME`); the daemon records both but authenticates neither: authorization is
the router's access control (config/zenoh/lab-router.json5).
"""

from __future__ import annotations

import getpass
import itertools
import json
import re
from typing import Any

from pamd.net import zconf
from pamd.net.keys import ROOT, Keys
from pamd.net.zconf import NoDaemon

DEFAULT_TIMEOUT_S = 3.0


class Client:
    def __init__(self, zenoh_config: str | None = None, connect: str | None = None) -> None:
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

    def close(self) -> None:
        self.session.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: Any) -> None:
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
        """`rig` itself, or the one rig alive; NoDaemon if none, or several."""
        if rig:
            return rig
        rigs = self.rigs(timeout_s)
        if not rigs:
            raise NoDaemon(f"no pamd daemon is alive via {self.where} (none declares "
                           f"{ROOT}/<rig>/alive; is pamd running with telemetry on?)")
        if len(rigs) > 1:
            raise NoDaemon(f"several rigs are alive ({', '.join(rigs)}); pick one with --rig")
        return rigs[0]

    # -- queries ----------------------------------------------------------------------------
    def _get(self, selector: str, payload: bytes | None, timeout_s: float) -> dict[str, Any]:
        z = self.zenoh
        kw: dict[str, Any] = {"timeout": timeout_s,
                              "congestion_control": z.CongestionControl.DROP}
        if payload is not None:
            kw.update(payload=payload, encoding=z.Encoding.APPLICATION_JSON,
                      source_info=z.SourceInfo(self.session.id, next(self._sn)))
        for r in self.session.get(selector, **kw):
            if r.ok is not None:
                try:
                    return json.loads(r.ok.payload.to_bytes())
                except ValueError:
                    return {"ok": False, "error": "the reply is not JSON: "
                            + r.ok.payload.to_bytes()[:200].decode("utf-8", "replace")}
            if r.err is not None:
                return {"ok": False, "error": r.err.payload.to_bytes().decode("utf-8",
                                                                              "replace")}
        key = selector.split("?", 1)[0]
        raise NoDaemon(f"no answer on {key} within {timeout_s:g} s via {self.where} (no "
                       "daemon for that rig, telemetry off, or not allowed: a viewer "
                       "cannot command)")

    def status(self, rig: str, timeout_s: float = DEFAULT_TIMEOUT_S) -> dict[str, Any]:
        return self._get(Keys(rig).status, None, timeout_s)

    def command(self, rig: str, verb: str, payload: dict[str, Any] | str | bytes | None = None,
                user: str | None = None, timeout_s: float = 10.0) -> dict[str, Any]:
        """Send a command; the reply is the loop's verdict (or the io process's
        refusal). A str/bytes payload is sent as is (malformed JSON too)."""
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
        return self._get(sel, body, timeout_s)

    def subscribe(self, key: str, capacity: int = 4096) -> Any:
        """A subscriber with a ring channel (`try_recv`, no callback thread)."""
        return self.session.declare_subscriber(key, self.zenoh.handlers.RingChannel(capacity))

"""What the client library says when zenoh answers a query with an error: its own
"Timeout" (the query's time ran out: the command may not have reached the daemon on a
congested link, or was answered too late) becomes a sentence that says what to do next; a rig's own
error text passes through as it is. A fake session stands in for zenoh's, so nothing
opens a socket here."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from pamd.client.remote import Client


@dataclass
class _Payload:
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class _Err:
    payload: _Payload


@dataclass
class _Reply:
    err: _Err
    ok: None = None


class _Session:
    def __init__(self, error: bytes) -> None:
        self.error = error
        self.id = "fake"

    def get(self, selector: str, **kw: object) -> list[_Reply]:
        return [_Reply(_Err(_Payload(self.error)))]


def _client(error: bytes) -> Client:
    zenoh = pytest.importorskip("zenoh")
    c = Client.__new__(Client)  # no session opened: the fake answers
    c.__dict__.update(zenoh=zenoh, _session=_Session(error), where="fake", _nonces={},
                      _closed=False)
    return c


def test_zenohs_timeout_says_the_command_may_be_lost_and_what_to_do() -> None:
    v = _client(b"Timeout").status("sim", timeout_s=2.5)
    assert v["ok"] is False
    assert v["error"].startswith("no answer within 2.5 s: the command may not have reached "
                                 "the daemon")
    assert "check the rig's status before sending it again" in v["error"]
    assert "never dropped" not in v["error"]  # an estop of 4 MiB was, saying so


def test_any_other_error_passes_through_unchanged() -> None:
    assert _client(b"denied: a viewer cannot command").status("sim")["error"] == (
        "denied: a viewer cannot command")

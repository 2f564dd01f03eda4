"""The key space of one rig, `pamd/<rig_id>/...`, mirrored by the MCAP topic names
(`/pamd/<rig_id>/state/<muscle>`, `/pamd/<rig_id>/events`)."""

from __future__ import annotations

import re

ROOT = "pamd"
#: rig ids and muscle names that are safe as one key chunk (no '/', '*', '$', '?', '#')
CHUNK_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


def check_chunk(what: str, value: str) -> str | None:
    """None when `value` can be one chunk of a key; else what is wrong with it."""
    if CHUNK_RE.match(value):
        return None
    return (f"{what} {value!r} cannot be part of a Zenoh key: use letters, digits, '_', "
            "'-' and '.'")


class Keys:
    """Every key of one rig."""

    def __init__(self, rig_id: str) -> None:
        self.rig_id = rig_id
        self.base = f"{ROOT}/{rig_id}"
        self.events = f"{self.base}/events"
        self.status = f"{self.base}/status"
        self.alive = f"{self.base}/alive"
        self.cmd_all = f"{self.base}/cmd/*"
        self.state_all = f"{self.base}/state/*"

    def state(self, muscle: str) -> str:
        return f"{self.base}/state/{muscle}"

    def cmd(self, verb: str) -> str:
        return f"{self.base}/cmd/{verb}"

    @staticmethod
    def last_chunk(key: str) -> str:
        return key.rsplit("/", 1)[-1]

    @staticmethod
    def rig_of(key: str) -> str:
        """The rig id of any key of the space (`pamd/<rig>/...`)."""
        parts = key.split("/")
        return parts[1] if len(parts) > 1 and parts[0] == ROOT else ""

"""The key space of one rig, `pamd/<rig_id>/...`, mirrored by the MCAP topic names
(`/pamd/<rig_id>/state/<muscle>`, `/pamd/<rig_id>/events`)."""

from __future__ import annotations

ROOT = "pamd"


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

"""The loop side's own argument types: a `model` command once its file is compiled
(`PreparedModelArgs`) and the internal `reload` (`ReloadArgs`), which carry live
objects no client sends. The argument schemas a client's payload is parsed into are
`pamd.wire.verbs.args`."""

from __future__ import annotations

from dataclasses import dataclass

from pamd.loop.control.feedforward import Feedforward
from pamd.loop.control.settings import MuscleSettings
from pamd.wire.declare.jsonsafe import JsonObject


class PreparedModelArgs:
    """A `model` command whose file was loaded, checked and compiled outside the loop's
    thread (`prepare_command`); the loop only swaps `feedforward` in."""

    def __init__(self, muscle: str, file: str, feedforward: Feedforward) -> None:
        self.muscle, self.file, self.feedforward = muscle, file, feedforward

    def describe(self) -> JsonObject:
        return {"muscle": self.muscle, **self.feedforward.describe()}


@dataclass(frozen=True, kw_only=True)
class ReloadArgs:
    """The `reload` command (SIGHUP). Internal (`VerbSpec.internal`), so no client can send
    it; the daemon builds it from a validated config. `plan` (one MuscleSettings per
    muscle, in the rig's order) stays out of the recorded event, like collect's."""

    config_sha256: str
    at_once: tuple[str, ...]  # changed key paths that apply at once (gains, timeouts)
    idle_only: tuple[str, ...]  # changed key paths that apply only while IDLE (limits)
    startup_timeout_s: float
    plan: tuple[MuscleSettings, ...]

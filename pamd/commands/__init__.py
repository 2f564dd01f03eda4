"""Commands to the running loop: their argument schemas and what each one does.

`parse_command` checks a payload's shape (unknown fields, types, NaN) and can run
anywhere (the io process does it before anything reaches the loop).
`apply_command` runs in the loop's thread at the start of a tick, checks the
command against the present state and limits, and returns the verdict. A refused
command changes nothing.

Modules: `schema` (argument schemas, `parse_command`, `prepare_command`), `apply`
(`apply_command`), and the handlers by kind: `motion`, `rig`, `plan`, sharing `guards`.
"""

from pamd.commands.apply import apply_command
from pamd.commands.schema import (
    LENGTH_PROFILE_FIELDS,
    VERBS,
    CollectArgs,
    Command,
    EstopArgs,
    HomeArgs,
    LoadArgs,
    ModeArgs,
    ModelArgs,
    MuscleArgs,
    MuscleSettings,
    NoArgs,
    PreparedModelArgs,
    ProfileArgs,
    ReloadArgs,
    SetpointArgs,
    parse_command,
    prepare_command,
)

__all__ = [
    "LENGTH_PROFILE_FIELDS", "VERBS", "CollectArgs", "Command", "EstopArgs", "HomeArgs",
    "LoadArgs", "ModeArgs", "ModelArgs", "MuscleArgs", "MuscleSettings", "NoArgs",
    "PreparedModelArgs", "ProfileArgs", "ReloadArgs", "SetpointArgs", "apply_command",
    "parse_command", "prepare_command",
]

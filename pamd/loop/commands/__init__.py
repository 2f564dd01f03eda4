"""Commands to the running loop: their verbs, argument schemas and what each one does.

The loop side of the command verbs: each verb's handler, declared in the module of
its group (`motion`, `rig`, `plan`, `tune`, `adapt`, sharing `guards`) against its spec in
`pamd.wire.verbs.table.VERBS` (name, argument dataclass, routing, help: what the io process
parses and routes by, without these modules); `verbs.REGISTRY` holds them all.
`parse_command` (`pamd.wire.verbs.table`, re-exported) checks a payload's shape;
`prepare_command` does a command's I/O (a `model` file) outside the loop's thread.
`apply_command` (`apply`) runs in the loop's thread at the start of a tick, checks the
command against the present state and limits, and returns the verdict. A refused
command changes nothing.
"""

from pamd.loop.commands.apply import apply_command
from pamd.loop.commands.parse import parse_command, prepare_command
from pamd.loop.commands.prepared import PreparedModelArgs, ReloadArgs
from pamd.loop.commands.verb_registry import Verb, VerbRegistry
from pamd.loop.commands.verbs import REGISTRY
from pamd.loop.control.settings import MuscleSettings
from pamd.wire.verbs.args import (
    LENGTH_PROFILE_FIELDS,
    CollectArgs,
    Command,
    EstopArgs,
    HomeArgs,
    LoadArgs,
    ModeArgs,
    ModelArgs,
    NoArgs,
    ProfileArgs,
    SetpointArgs,
)

__all__ = [
    "LENGTH_PROFILE_FIELDS", "REGISTRY", "CollectArgs", "Command", "EstopArgs", "HomeArgs",
    "LoadArgs", "ModeArgs", "ModelArgs", "MuscleSettings", "NoArgs",
    "PreparedModelArgs", "ProfileArgs", "ReloadArgs", "SetpointArgs", "Verb", "VerbRegistry",
    "apply_command", "parse_command", "prepare_command",
]

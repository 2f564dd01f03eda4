"""Commands to the running loop: their verbs, argument schemas and what each one does.

A verb is declared once (`registry.Verb`: argument dataclass, handler, routing
properties, CLI help) in the module of its kind (`motion`, `rig`, `plan`, sharing
`guards`); `verbs.REGISTRY` holds them all and everything else derives from it.
`parse_command` (`parse`) checks a payload's shape (unknown fields, types, NaN) and can
run anywhere (the io process does it before anything reaches the loop);
`prepare_command` does a command's I/O (a `model` file) outside the loop's thread.
`apply_command` (`apply`) runs in the loop's thread at the start of a tick, checks the
command against the present state and limits, and returns the verdict. A refused
command changes nothing.
"""

from pamd.commands.apply import apply_command
from pamd.commands.parse import parse_command, prepare_command
from pamd.commands.registry import Verb, VerbRegistry
from pamd.commands.schema import (
    LENGTH_PROFILE_FIELDS,
    CollectArgs,
    Command,
    EstopArgs,
    HomeArgs,
    LoadArgs,
    ModeArgs,
    ModelArgs,
    MuscleSettings,
    NoArgs,
    PreparedModelArgs,
    ProfileArgs,
    ReloadArgs,
    SetpointArgs,
)
from pamd.commands.verbs import REGISTRY

__all__ = [
    "LENGTH_PROFILE_FIELDS", "REGISTRY", "CollectArgs", "Command", "EstopArgs", "HomeArgs",
    "LoadArgs", "ModeArgs", "ModelArgs", "MuscleSettings", "NoArgs",
    "PreparedModelArgs", "ProfileArgs", "ReloadArgs", "SetpointArgs", "Verb", "VerbRegistry",
    "apply_command", "parse_command", "prepare_command",
]

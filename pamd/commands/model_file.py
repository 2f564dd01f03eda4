"""The `model` command's preparation, outside the loop's thread: its file read (or its
bytes, already read within the limits by the caller), checked against the muscle and
compiled, so the loop only swaps the compiled object in (`Verb.prepare`)."""

from __future__ import annotations

import dataclasses
import os

from pamd.commands.schema import MAX_ERROR_CHARS, Command, PreparedModelArgs, cap_text
from pamd.config.loader import LoadedConfig
from pamd.control.feedforward import Feedforward, LoadedModel
from pamd.errors import CommandRefused, ModelError


def prepare_model(cmd: Command, cfg: LoadedConfig, data: bytes | None) -> Command:
    """`cmd` with its model loaded (PreparedModelArgs); CommandRefused if it cannot be.
    With `data` the bytes are taken as they are: one read, nothing can change between
    the check and the load."""
    if isinstance(cmd.args, PreparedModelArgs):
        return cmd
    a = cmd.args
    try:
        mcfg = cfg.muscle(a.muscle)
    except KeyError:
        names = ", ".join(m.name for m in cfg.rig.muscles)
        raise CommandRefused(f"no muscle named {a.muscle!r}; muscles: {names}") from None
    path = os.path.abspath(os.path.expanduser(a.file))
    try:
        if data is None:
            ff = Feedforward.from_file(path, mcfg, cfg.limits[a.muscle])
        else:
            ff = LoadedModel.from_bytes(data, path, mcfg, cfg.limits[a.muscle]).feedforward()
    except ModelError as exc:
        raise CommandRefused(cap_text(f"model refused: {exc}", MAX_ERROR_CHARS)) from None
    except OSError as exc:
        raise CommandRefused(f"model refused: {a.file}: {exc.strerror or exc}") from None
    except (RecursionError, UnicodeDecodeError, ValueError) as exc:
        raise CommandRefused(f"model refused: {a.file}: unreadable as a model file "
                             f"({exc.__class__.__name__})") from None
    return dataclasses.replace(cmd, args=PreparedModelArgs(a.muscle, path, ff))

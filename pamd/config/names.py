"""What a name in the config may be: muscle and driver names, and the rig id, which
become chunks of Zenoh keys (`pamd/<rig_id>/...`) and MCAP topic names."""

from __future__ import annotations

import re

#: muscle, driver and step names
NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
#: rig ids and muscle names that are safe as one key chunk (no '/', '*', '$', '?', '#')
CHUNK_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


def check_chunk(what: str, value: str) -> str | None:
    """None when `value` can be one chunk of a key; else what is wrong with it."""
    if CHUNK_RE.match(value):
        return None
    return (f"{what} {value!r} cannot be part of a Zenoh key: use letters, digits, '_', "
            "'-' and '.'")

"""The one JSON encoder of what pamd says (events in the recording and on Zenoh, the
status snapshot, the recording's metadata): strict JSON, which Foxglove and browsers
parse, so a non-finite float (NaN: no value) becomes null."""

from __future__ import annotations

import json
import math
from typing import Any


def jsonsafe(x: object) -> Any:
    """Strict-JSON copy: non-finite floats become null, keys strings, tuples lists."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): jsonsafe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonsafe(v) for v in x]
    return x


def dumps(x: object) -> str:
    """Compact strict JSON of `x` (after `jsonsafe`); what JSON cannot hold is written
    as its text (an event is never lost to an odd value)."""
    return json.dumps(jsonsafe(x), separators=(",", ":"), default=str)

"""The one JSON encoder of what pamd says (events in the recording and on Zenoh, the
status snapshot, the recording's metadata): strict JSON, which Foxglove and browsers
parse, so a non-finite float (NaN: no value) becomes null."""

from __future__ import annotations

import json
import math
from typing import Any, TypeAlias

# The types of JSON and YAML values at pamd's edges, named once (here, beside the one
# JSON encoder, so the io process imports no extra module for them).
#
# Any: pamd's one untyped data, named here once (`mypy --strict` runs over pamd/ and
# drivers/; every other use says beside it, after `# Any:`, why it is one). A JSON or
# YAML value is whatever its text said until a checker narrows it, so its static type
# is the edge's:
#
# * in: a command's payload (checked by pamd.wire.verbs), a config file's nodes (pamd.wire.schema,
#   pamd.config, which name file, line and key), a model file (pamd.models.document),
#   a status answer, a recording's metadata or events (pamd.wire.record, pamd.client);
# * out: an event's payload, a verdict, the status, a model file's provenance and
#   metrics: any value `jsonsafe` below can write (it writes what JSON cannot hold
#   as its text).
#
# A recursive union (`dict[str, JsonValue] | list[JsonValue] | str | float | ...`) would
# make every reader narrow each step again after the checker did; the aliases name the
# edge instead, so a reader sees that the dict came from (or goes to) JSON.

#: a JSON or YAML value: object, array, string, number, bool or null (see above)
JsonValue: TypeAlias = Any  # Any: the JSON/YAML edge, as explained above
#: a JSON or YAML object: keys are strings, values `JsonValue`s
JsonObject: TypeAlias = dict[str, Any]  # Any: the JSON/YAML edge, as explained above


def jsonsafe(x: object) -> JsonValue:
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

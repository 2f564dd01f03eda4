"""An adapted model as a new model file: the source model file (as `pamd train` wrote
it) with the consequents a running daemon adapted (`pamd.loop.control.adapt`, the `adapt`
command's ``parameters``) and their provenance.

The daemon's loop only copies its parameters into the command's verdict between two
ticks; this module, in the client (`pamd model save`) or any process but the loop's,
reads the source file, checks it is the one the daemon loaded (its sha256), and
writes the new file in the same format, readable by `pamd run --model`, `pamd
evaluate` and the `model` command. The file's ``provenance.adapted`` says from what
and how: the source file and its sha256, when adaptation started and how long it
ran, its bounds, and how far the model moved (``total_bar``: the largest output
change anywhere in the training ranges; ``drift_bar`` at the last sample). The
``metrics`` kept are the source model's (on its own training data).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import os
from pathlib import Path

import numpy as np

from pamd.models.anfis.model import AnfisModel
from pamd.models.registry import load_model, save_model
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError


def _iso(unix: float | None) -> str | None:
    if unix is None:
        return None
    return dt.datetime.fromtimestamp(unix, dt.timezone.utc).isoformat(timespec="seconds")


def adapted_model(source: AnfisModel, snapshot: JsonObject) -> AnfisModel:
    """`source` (modified in place and returned) with the snapshot's consequents and
    the provenance of the adaptation."""
    theta = np.asarray(snapshot["consequents"], dtype=np.float64)
    r, d, cols = source.n_rules, source.n_inputs, source.n_consequent_columns
    if theta.shape != (cols * r,) or not np.isfinite(theta).all():
        raise ModelError(f"adapted consequents: expected {cols * r} finite values for "
                         f"{r} rules and {d} inputs ({source.consequent} consequents), "
                         f"got {theta.size}")
    full = np.zeros((r, d + 1))
    full[:, -cols:] = theta.reshape(cols, r).T  # p stay 0 if constant
    source.consequents = full
    keys = ("muscle", "updates", "adapted_s", "drift_bar", "total_bar", "refused",
            "rate_limited", "state", "bounds")
    source.provenance = {**source.provenance, "adapted": {
        "source_file": snapshot.get("source"), "source_sha256": snapshot.get("sha256"),
        "started": _iso(snapshot.get("started_unix")),
        "saved": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
        "method": "recursive least squares with forgetting on the rule consequents "
                  "(pamd.loop.control.adapt); metrics are the source model's",
        **{k: snapshot.get(k) for k in keys}}}
    return source


def save_adapted(snapshot: JsonObject, out: str | os.PathLike[str],
                 source_file: str | None = None) -> Path:
    """Write the adapted model to `out` from the `adapt parameters` verdict; the source
    model file is the one it names (or `source_file`) and must have its sha256.
    ModelError says why not."""
    src = source_file or snapshot.get("source")
    if not src:
        raise ModelError("the adapted model names no source file: give it (--source)")
    try:
        data = Path(src).read_bytes()
    except OSError as exc:
        raise ModelError(f"source model {src}: cannot read it ({exc.strerror or exc}); "
                         "give the file the daemon loaded with --source") from None
    sha = hashlib.sha256(data).hexdigest()
    if snapshot.get("sha256") and sha != snapshot["sha256"]:
        raise ModelError(f"source model {src} is not the file the daemon adapted (sha256 "
                         f"{sha[:12]}..., the daemon's {str(snapshot['sha256'])[:12]}...)")
    model = load_model(data, name=str(src))
    if not isinstance(model, AnfisModel):
        raise ModelError(f"source model {src} is a {model.kind} model: only ANFIS and "
                         "TS-fuzzy models adapt")
    path = save_model(adapted_model(model, snapshot), out)
    load_model(path.read_bytes(), name=str(path))  # it loads as any model file does
    return path

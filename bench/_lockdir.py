"""The benchmarks' simulated rigs are each their own: their rig locks
(pamd.service.riglock) go in a directory of this run, so benchmarks run at once on one
machine, or beside a `sim` daemon, do not refuse each other. Imported for its effect,
first, by every benchmark that starts a daemon (bench/_common.py does it for its users)."""

from __future__ import annotations

import os
import tempfile

os.environ.setdefault("PAMD_LOCK_DIR", tempfile.mkdtemp(prefix="pamd-bench-locks-"))

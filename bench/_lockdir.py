"""The benchmarks' simulated rigs are each their own: their locks (pamd.daemon.service.riglock)
and the state a real-clock run keeps (pamd.daemon.service.state) go in directories of this run,
so benchmarks run at once on one machine, or beside a `sim` daemon, do not refuse each
other, and none writes into the user's ~/.local/state. Imported for its effect, first,
by every benchmark that starts a daemon (bench/_common.py does it for its users)."""

from __future__ import annotations

import os
import tempfile

os.environ.setdefault("PAMD_LOCK_DIR", tempfile.mkdtemp(prefix="pamd-bench-locks-"))
os.environ["XDG_STATE_HOME"] = tempfile.mkdtemp(prefix="pamd-bench-state-")

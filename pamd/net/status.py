"""The status snapshot, built by the daemon's main thread a few times a second (never
by the loop's thread, never per tick) and answered by the io process from the board.

Keys: `rig_id`, `state`, `reason`, `fault`, `faults`, `muscles` (measured values,
setpoints, limits, references, mode, profile, model, deadman), `experiment` (with the
`collection` a remote collect writes into: directory, manifest),
`config_sha256`, `clock`, `rate_hz`, `verbs`, `recording`, `pid` and `user` (whose
daemon it is), `t_wall_s`, `uptime_s`.
It costs the main thread some 50 us. The io process, when it answers, puts in the
live values of the latest tick record it drained (state, measured values, setpoint,
valve command, mode, flags), `timing` (from the tick records: pamd.net.node.stats), `ok`,
`snapshot_age_s` and `io` (its own counters).
"""

from __future__ import annotations

from pamd.declare.jsonsafe import jsonsafe as jsonsafe  # the one JSON encoder's

"""Running pamd as a systemd service: the notify protocol (`notify`), state that
survives restarts (`state`: the latched fault and the last known-good safe
outputs), the main-thread keeper that ties both to a running daemon (`keeper`),
config reload on SIGHUP (`reload`), the second-line `pamd safe-outputs` replay
(`safe_outputs`) and `pamd install-service` (`install`)."""

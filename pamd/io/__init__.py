"""The io process: where recording (`pamd.wire.record`), telemetry (`pamd.net`) and the
live view (`pamd.view`) run, away from the loop's interpreter lock.

- `spec`: the picklable description of one io process.
- `process`: the io process's main loop (drain rings, record, serve, heartbeat).
- `link`: the loop-process side (start/watch the process, sink, mailbox).
- `session`: the daemon's handle on one io process and what it hosts.
"""

"""The io process and what it does: MCAP recording (and, later, Zenoh telemetry).

- `spec`: the picklable description of one io process (what to record, where).
- `cdr`: message schemas (ros2msg) and precompiled CDR encoders/decoders.
- `mcapw`: a small chunked MCAP writer built for the hot path and crash safety.
- `recorder`: topics, metadata, file naming and rotation on top of `mcapw`.
- `process`: the io process's main loop (drain rings, record, heartbeat).
- `link`: the loop-process side (start/watch the process, sink, mailbox).
- `control`: recording control from the daemon's main thread (a remote collection's
  directory and steps) and the recorder's notices back.
- `files`: reading recordings back: inspect, export, recover.
"""

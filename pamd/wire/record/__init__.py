"""Recordings: MCAP files written crash-safe, and read back.

- `spec`: one run's recording (`RecordSpec`) and what the recorder needs of the run.
- `cdr`: message schemas (ros2msg) and precompiled CDR encoders/decoders.
- `mcapw`: a small chunked MCAP writer built for the hot path and crash safety.
- `recorder`: topics, metadata, file naming and rotation on top of `mcapw`.
- `meta`: a run's recording spec and metadata from the config.
- `control`: recording control from the daemon's main thread (a remote collection's
  directory and steps) and the recorder's notices back.
- `files`: reading recordings back: inspect, export, recover.
"""

"""Seeing the rig: live in Foxglove, and its recordings afterwards.

- `spec`: what the live view of a run is (config, `pamd run --foxglove`).
- `live`: the Foxglove WebSocket server of the io process (never the loop's process):
  the recording's channels and schemas, decimated like the Zenoh state.
- `layout`: the Foxglove layout shipped as config/foxglove/pamd-layout.json.
- `recording`: `pamd.open_recording`, a recording or a collection as numpy arrays or
  pandas DataFrames, with units, state and mode names, events and metadata.
- `client`: `pamd.connect`, a running daemon over Zenoh for scripts and notebooks.
- `export`: MATLAB (.mat) and named CSV files of a recording.
- `plots`: `pamd plot`, the figures of a run without a model.
- `collection`: what a collection directory holds (`pamd inspect DIR`).
- `fields`: units, state and mode names, flag bits of the recorded fields.
"""

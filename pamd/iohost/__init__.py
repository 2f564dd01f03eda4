"""The io process: the recorder (MCAP), the Zenoh node, the Foxglove live view,
fed by the loop's rings and the daemon's board (`pamd.wire`); it imports nothing
else of pamd (tests/io/test_io_imports.py counts it)."""

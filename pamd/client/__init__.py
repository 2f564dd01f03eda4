"""The client side: the Python API (`pamd.connect`, `pamd.open_recording`), the
recordings' tools (export, plots, collections), and the command line (`cli`,
`commission`, `tune`)."""

"""Live telemetry, status and remote commands over Zenoh.

The Zenoh session lives in the io process (`pamd.iohost.process`), never in the loop's
process: Zenoh's Python callbacks run on their own threads and take the interpreter
lock. The io process polls Zenoh's channels from its own single thread (`node`),
publishes decimated, batched state and the loop's events, answers `status` from a
snapshot the daemon's main thread writes a few times a second (`board`, `host`),
and passes commands through the command mailbox to the loop, replying only with the
loop's verdict. `client` is the other end (the CLI's `status`, `cmd`, `watch`).

Key space (`keys`): `pamd/<rig_id>/state/<muscle>`, `.../events`, `.../status`,
`.../cmd/<verb>`, and the liveliness token `.../alive`.
"""

"""What crosses a process boundary, in one package: the tick record and the field
table, the event registry, the rings, the verbs' specs, the status board and its
status, the recording format and its readers, what Zenoh, the local channel and
the command credential share, and the leaves they need (errors, version, the
schema engine, the one file writer). Every process imports it; it imports no
other package of pamd."""

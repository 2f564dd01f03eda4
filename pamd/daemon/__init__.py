"""The main process: the daemon that wires the loop and the io process, the
service keeper (systemd, reload, restart, persistence), the requests that need
the main thread and the status snapshot (`host`)."""

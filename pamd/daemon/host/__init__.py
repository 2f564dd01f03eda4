"""The daemon's (main process's) side of telemetry: the status snapshot it writes a few
times a second (`status`), the requests that need its main thread (`host`: a `model`
file compiled, a `collect` plan read) and the collections started over the network
(`collections`). Reached through small ports (`ports`), never the daemon itself."""

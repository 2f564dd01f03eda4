"""The emulated rig: the simulated muscles (pamd.sim) served through real field-bus
protocols from a separate process (`pamd emulate`), so the daemon's real drivers
can be run end to end without hardware. See `rig.EmulatedRig`."""

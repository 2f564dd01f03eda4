"""pamd.sim: the simulated rig behind the `sim` driver (`pamd.drivers.sim`).

`options` holds its option dataclasses, `plant` the physics of one muscle with its
hanging load and sensors, `regulator` the proportional pressure regulator.
"""

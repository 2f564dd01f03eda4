"""`pamd commission`: measure a rig's signals and timing at rest and in small, slow
moves inside its limits, check the signs and scaling of its sensors, and derive the
sensor and timing thresholds of its config from what was measured."""

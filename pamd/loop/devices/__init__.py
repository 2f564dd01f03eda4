"""The rig's devices as the tick sees them: drivers built from the config, each
muscle's signals bound to driver channels (`bindings`), and the datums (home,
tare) kept beside the config (`datum_file`)."""

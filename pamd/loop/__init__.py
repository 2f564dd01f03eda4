"""The loop process: the fixed-rate loop and its end of the rings, the rig
controller and each muscle's stages (`control`), safety, the devices and their
datums (`devices`), the verbs' loop side (`commands`), the experiment
sequencer (`experiment`)."""

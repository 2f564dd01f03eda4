"""`pamd tune`: identify a loop on the rig from recorded steps and derive its gains."""

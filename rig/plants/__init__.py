"""Plant models: the physical systems the rig simulates."""

"""sim.validate."""

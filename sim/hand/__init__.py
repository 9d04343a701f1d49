"""sim.hand."""

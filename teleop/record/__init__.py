"""teleop.record."""

"""teleop.input."""

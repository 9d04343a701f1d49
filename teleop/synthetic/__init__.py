"""teleop.synthetic."""

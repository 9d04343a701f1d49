"""teleop.bridge."""

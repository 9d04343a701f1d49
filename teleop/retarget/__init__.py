"""teleop.retarget."""

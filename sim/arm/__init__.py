"""Arms that carry a hand: arm configs (``configs/arms/<arm>/arm.toml``), the hand–arm–table
scene composed with ``mujoco.MjSpec`` and whole-body IK with mink that puts the hand's
``frame_palm`` on a grasp's palm pose (paper §5.3). Like the rest of ``sim``, nothing here
knows a particular arm or hand: both come from their configs."""

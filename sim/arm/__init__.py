"""Arms that carry a hand (paper §5.3): configs, the hand–arm–table scene, IK, plans, simulation.

What it holds: :mod:`~sim.arm.config` (``configs/arms/<arm>/arm.toml``), :mod:`~sim.arm.scene`
(the hand on the arm's flange with a table and an object, composed with ``mujoco.MjSpec``),
:mod:`~sim.arm.ik` (whole-body IK with mink that puts the hand's ``frame_palm`` on a grasp's palm
pose), :mod:`~sim.arm.placement` (objects as they lie on the table, grasps carried to them),
:mod:`~sim.arm.plan` (pregrasp, approach, grasp and lift, collision-checked),
:mod:`~sim.arm.simulate` (a planned grasp run in MuJoCo) and :mod:`~sim.arm.evaluate` (hand-only
grasps evaluated on an arm, placement by placement).

What to import: ``from sim.arm.evaluate import evaluate_on_arm`` for the whole evaluation, the
scene, IK and plan from their modules. Like the rest of ``sim``, nothing here knows a particular arm or hand:
both come from their configs.
"""

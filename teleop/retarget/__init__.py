"""Retargeting: an operator's tracked hand → a robot hand's joint vector and wrist pose (mink).

What it holds: :mod:`~teleop.retarget.retargeter` (``Retargeter``: one IK step per frame, daqp),
its settings (:mod:`~teleop.retarget.config`: ``[retarget]`` and each hand's ``retarget.toml``)
and result (:mod:`~teleop.retarget.result`); the operator's points
(:mod:`~teleop.retarget.operator_points`) and their smoothing
(:mod:`~teleop.retarget.input_filter`, One-Euro) and the output filter
(:mod:`~teleop.retarget.joint_filter`); the IK's own tasks (:mod:`~teleop.retarget.tasks`);
the object surface and snapping pads onto it (:mod:`~teleop.retarget.surface`,
:mod:`~teleop.retarget.snap`); per-operator calibration (:mod:`~teleop.retarget.calibration`);
offline retargeting of a whole recording (:mod:`~teleop.retarget.trace`).

What to import: ``from teleop.retarget.retargeter import Retargeter``
(``Retargeter(hand).step(hand_state)``) and ``retarget_frames`` from
:mod:`~teleop.retarget.trace` for recordings. Units: metres, radians.
"""

"""A synthetic operator: grasp sessions as hand-tracking frames, without a headset.

What it holds: the operator's hand (:mod:`~teleop.synthetic.human_hand`: 26 OpenXR joints from a
parametric adult hand), where it must be for a grasp (:mod:`~teleop.synthetic.grasp_pose`,
:mod:`~teleop.synthetic.correspondence`, :mod:`~teleop.synthetic.grasp_search`,
:mod:`~teleop.synthetic.surface`) and how it reaches (:mod:`~teleop.synthetic.preshape`), the
episode's phases and motion (:mod:`~teleop.synthetic.episode`), the headset's sensor model
(:mod:`~teleop.synthetic.sensor`), and putting it together (:mod:`~teleop.synthetic.synthesize`,
:mod:`~teleop.synthetic.writer`: an MCAP session that replays like a real one;
:mod:`~teleop.synthetic.scripted`: a grasp performed in the bridge's scene and recorded), with
its settings (:mod:`~teleop.synthetic.config`).

What to import: ``from teleop.synthetic.synthesize import synthesize`` and
``from teleop.synthetic.writer import write_session`` for a session, or
``record_scripted_demo`` from :mod:`~teleop.synthetic.scripted` for a recorded demonstration.
"""

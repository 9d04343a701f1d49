"""Validated grasps as trajectories (DESIGN §8, issue #55).

A grasp is rolled out by the validator's own scene, placement and lift-drop program
(:func:`sim.episodes.rollout.rollout`): every physics step of the run is recorded as one step
of an :class:`sim.episodes.episode.Episode` (the actions the protocol gave, the hand's and the
object's states, the fingertip contacts, the stage, the time), and the episode's verdict is the
validator's own. :func:`sim.episodes.replay.replay` plays an episode's actions again in any
scene of the same model and gives the states back, which is how an exported trajectory is
checked against the simulation.
"""

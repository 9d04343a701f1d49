"""The grasp scene as a ``dm_env`` environment built with dm-control (DESIGN §8, issue #55).

:func:`sim.envs.grasp_env.grasp_env` gives a ``dm_control.rl.control.Environment`` whose
episodes start at a dataset grasp's pregrasp and are rewarded and ended by the lift-drop
protocol (:mod:`sim.envs.referee`). dm-control is the optional ``envs`` extra
(``pip install 'dexaug[envs]'``); only :mod:`sim.envs.grasp_env` imports it.
"""

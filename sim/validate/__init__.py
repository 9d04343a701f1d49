"""Grasp validation in MuJoCo: a grasp is placed, closed and put through a protocol's program
(lift-drop, six-direction shaking, the DexGraspBench benchmark's ``dgb``), and the verdict comes
back with its metrics and the reason it failed (``result.py``).

``validator.py`` places and runs one grasp; the protocols are plug-ins under ``protocols/``
(one module each, registered in ``protocols/registry.py``); ``batch.py`` spreads many grasps
over worker processes, ``batched.py`` and ``warp_runner.py`` run many worlds at once (MuJoCo's
batch rollouts, MuJoCo Warp on a GPU); ``diagnose*.py`` say why a grasp fails.
"""

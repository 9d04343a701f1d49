"""Robot hands: a hand folder's config bound to its MuJoCo model.

What it holds: :mod:`~sim.hand.config` reads ``configs/hands/<hand>/hand.toml`` (model, palm
frame, fingers, coupling, workspace ranges, postures, mount, the ``[formats.*]`` other tools'
files know it by) and names the default hand; :mod:`~sim.hand.model` is the :class:`Hand`
(the compiled model, joint and finger names, qpos → ctrl, body poses by forward kinematics);
:mod:`~sim.hand.kinematics` its batched NumPy forward kinematics; :mod:`~sim.hand.conventions`
and :mod:`~sim.hand.model_checks` check a config against dexaug's palm-frame convention and its
model; :mod:`~sim.hand.reference_grasps` reads a hand's hand-built grasps (``grasps.toml``).

What to import: ``from sim.hand.model import Hand`` (``Hand.load(name)``) for a hand;
``from sim.hand.config import load_hand_config, hand_names, default_hand_name`` for its config
without compiling the model. Nothing here names a particular hand: all of it is in the folders.
"""

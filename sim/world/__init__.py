"""The simulated world around a hand: objects, scenes, contacts, closing and images.

What it holds: objects — :mod:`~sim.world.objects` (``ObjectAsset``, ``load_object``: YCB MJCF
files and procedural primitives), :mod:`~sim.world.primitives`, :mod:`~sim.world.ycb_xml`,
:mod:`~sim.world.object_spec`, :mod:`~sim.world.catalog` (what exists and loads), resting poses
on a table (:mod:`~sim.world.resting`, :mod:`~sim.world.rest_drop`); scenes —
:mod:`~sim.world.scene` (``Scene``: floating hand, free object, optional table, built with
``MjSpec``; ``PhysicsOptions``) and :mod:`~sim.world.hand_spec` (a protocol's edits of the hand);
reading it — :mod:`~sim.world.contacts` (hand–object contacts as arrays),
:mod:`~sim.world.geom_mesh`; acting in it — :mod:`~sim.world.closing` (closing a hand on an
object); images — :mod:`~sim.world.render` (offscreen MuJoCo renderer) and
:mod:`~sim.world.drawing` (PNG/JPEG and a canvas on NumPy images).

What to import: ``from sim.world.objects import load_object`` and
``from sim.world.scene import Scene`` for most uses; the rest from their modules. Units: SI,
quaternions w x y z.
"""

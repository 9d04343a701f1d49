"""The teleop bridge: one loop from tracked hands on zenoh to a simulated robot hand and back.

What it holds: the loop (:mod:`~teleop.bridge.bridge`, ``Bridge``; :mod:`~teleop.bridge.main`
runs it for ``dexaug bridge``) and its settings (:mod:`~teleop.bridge.config`); its control
queries and what an untrusted caller may ask (:mod:`~teleop.bridge.control`,
:mod:`~teleop.bridge.remote_args`); the scene's object (:mod:`~teleop.bridge.object_mode`,
:mod:`~teleop.bridge.object_watch`, :mod:`~teleop.bridge.session_mode`), the hand's entry and
grasp assist (:mod:`~teleop.bridge.entry`, :mod:`~teleop.bridge.grasp_assist`,
:mod:`~teleop.bridge.grasp_squeeze`, :mod:`~teleop.bridge.surface_feed`), contacts for the
recorder (:mod:`~teleop.bridge.scene_contacts`), fault handling (:mod:`~teleop.bridge.faults`),
the headset view and its stream (:mod:`~teleop.bridge.view`, :mod:`~teleop.bridge.view_stream`),
Foxglove live state (:mod:`~teleop.bridge.foxglove_live`) and re-recording a session through it
(:mod:`~teleop.bridge.rerecord`).

What to import: ``from teleop.bridge.bridge import Bridge`` and its ``BridgeConfig``
(:mod:`~teleop.bridge.config`); the rest serves the loop. Replay and live capture run the same
loop.
"""

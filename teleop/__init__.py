"""Teleoperation: from a person's tracked hands to a simulated robot hand, and recordings of it.

What it holds: the hand-tracking message schema (:mod:`teleop.messages`), zenoh keys
(:mod:`teleop.keys`), the one network-access policy of every server (:mod:`teleop.net_access`),
ingest from headsets and streamer apps (:mod:`teleop.input`), mink retargeting
(:mod:`teleop.retarget`), the zenoh bridge loop that steps the simulated hand
(:mod:`teleop.bridge`), MCAP recording, replay and demo extraction (:mod:`teleop.record`), and
a synthetic operator that makes sessions without a headset (:mod:`teleop.synthetic`).

What to import: ``from teleop.messages import HandFrame``,
``from teleop.retarget.retargeter import Retargeter``, ``from teleop.bridge.bridge import Bridge``
and the record/replay functions from :mod:`teleop.record`'s modules. It imports ``sim`` only,
never ``augment`` or ``dexaug``.
"""

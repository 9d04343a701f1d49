"""MuJoCo side of dexaug, and the common layer every other package builds on.

What it holds: hand models from their configs (:mod:`sim.hand`), objects, scenes, contacts and
rendering (:mod:`sim.world`), grasp-quality metrics (:mod:`sim.metrics`), the grasp validator
and its protocols (:mod:`sim.validate`), arms that carry a hand (:mod:`sim.arm`), replayable
episodes and a ``dm_env`` environment (:mod:`sim.episodes`, :mod:`sim.envs`); and the shared
record types and services of the whole project: :mod:`sim.grasp` (``Grasp``), :mod:`sim.demo`
(``Demo``), :mod:`sim.errors` (the one-line error types), :mod:`sim.config` (TOML sections that
name the file and key), :mod:`sim.paths`, :mod:`sim.io` (atomic writes), :mod:`sim.transforms`
(poses, quaternions w x y z), :mod:`sim.pools`, :mod:`sim.provenance`, :mod:`sim.versions`.

What to import: nothing from ``sim`` itself — import from the modules, e.g.
``from sim.hand.model import Hand``, ``from sim.world.objects import load_object``,
``from sim.validate.validator import Validator``. Everything here works on plain arrays and
MuJoCo models and never prints (the CLI reports); ``augment`` and ``teleop`` may import ``sim``,
never the other way (``tests/test_architecture.py``).
"""

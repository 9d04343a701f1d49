"""AutoWS (paper §3; DESIGN §4): each finger's workspace cloud in the palm frame.

What it holds: :mod:`~augment.autows.fingertip` — fingertip clouds and contact faces per finger
(fingertip frame); :mod:`~augment.autows.grids` — the joint grids (manual ranges, or centred on
a demonstration); :mod:`~augment.autows.build` — :func:`build_workspace`, forward kinematics of
every grid point into the clouds, filtered and skeletonised; :mod:`~augment.autows.cloud` — the
clouds as data (``FingerCloud``, ``WorkspaceCloud``) and their ``.npz`` format;
:mod:`~augment.autows.cache` — the on-disk cache keyed by hand, config and demo;
:mod:`~augment.autows.seed` — what AutoWS takes of a demo (``DemoSeed``);
:mod:`~augment.autows.params` — ``[autows]`` of ``configs/augment.toml``;
:mod:`~augment.autows.render` — the clouds drawn over the hand (the paper's Fig. 2).

What to import: ``from augment.autows.build import build_workspace`` (and ``DemoSeed`` from
:mod:`~augment.autows.seed` to centre it on a demo); the cloud types from
:mod:`~augment.autows.cloud`. Units: metres, radians.
"""

"""Grasp-quality numbers computed from contacts, independent of how the contacts were found.

What it holds: :mod:`~sim.metrics.gws` — the grasp wrench space's Q1 (ε) and hull volume with
GraspIt's conventions (friction-cone edges, torque over the object's largest radius; DESIGN §4,
§5); :mod:`~sim.metrics.holding` — the smallest total normal force (N) a set of contacts needs
to hold given loads (:class:`~sim.metrics.holding.HoldLoads`); :mod:`~sim.metrics.lp` — the
linear programme that rests on, built once and solved for many loads (HiGHS).

What to import: ``from sim.metrics.gws import gws_metrics`` (one grasp) or ``gws_metrics_batch``;
``from sim.metrics.holding import HoldLoads`` and its solvers. Pure NumPy/SciPy, no MuJoCo.
"""

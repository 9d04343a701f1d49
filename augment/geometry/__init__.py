"""Point-cloud and mesh geometry the augmenter is built from (AutoWS, paper §3.1).

What it holds: :mod:`~augment.geometry.sampling` — Poisson-disk samples of a triangle mesh with
outward normals; :mod:`~augment.geometry.visibility` — hidden point removal (Katz et al. 2007);
:mod:`~augment.geometry.pulp` — a fingertip cloud's pulp side; :mod:`~augment.geometry.contact_face`
— :func:`contact_face`, the flat patch of a fingertip that may touch an object;
:mod:`~augment.geometry.inscribed` — the largest circle or axis-aligned rectangle in a convex
polygon (the face's shape); :mod:`~augment.geometry.face` — the ``ContactFace`` record and its
error.

What to import: the function you need from its module
(``from augment.geometry.contact_face import contact_face``). Pure NumPy/SciPy; nothing here
knows a hand or MuJoCo. Units: metres.
"""

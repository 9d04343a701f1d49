"""The device kernels that run around one ``mujoco_warp.step`` of every world (ramp, pin, count).

Why a module of its own: Warp reads kernel annotations at definition, so this imports ``warp``
at the top and is itself imported only once :func:`sim.validate.warp_runner.import_warp` has
found it (MuJoCo Warp is optional). No ``from __future__ import annotations`` here: Warp needs
the annotations as objects.
"""

import warp as wp

__all__ = ["count", "pin", "ramp"]


@wp.kernel
def ramp(k: wp.array(dtype=wp.int32), nramp: wp.array(dtype=wp.int32),
         act: wp.array(dtype=wp.int32), c0: wp.array2d(dtype=wp.float32),
         c1: wp.array2d(dtype=wp.float32), ctrl: wp.array2d(dtype=wp.float32)):
    """Step k (0-based, ``k[0]``) of an n-step ramp sets the controls ``act`` to the blend at
    (k + 1)/n (:class:`sim.validate.program.Advance`); a world with n = 0 keeps its controls."""
    w, j = wp.tid()
    n = nramp[w]
    if n > 0:
        a = wp.float32(k[0] + 1) / wp.float32(n)
        ctrl[w, act[j]] = (1.0 - a) * c0[w, j] + a * c1[w, j]


@wp.kernel
def pin(pinned: wp.array(dtype=wp.int32), pose: wp.array2d(dtype=wp.float32), qadr: int,
        dadr: int, qpos: wp.array2d(dtype=wp.float32), qvel: wp.array2d(dtype=wp.float32)):
    """A pinned world's free object back at ``pose`` (position metres, wxyz) and at rest."""
    w, i = wp.tid()
    if pinned[w] != 0:
        qpos[w, qadr + i] = pose[w, i]
        if i < 6:
            qvel[w, dadr + i] = 0.0


@wp.kernel
def count(k: wp.array(dtype=wp.int32)):
    """One more step taken (the ramp's k)."""
    k[0] = k[0] + 1

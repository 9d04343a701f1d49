"""Coordinate and quaternion conventions of the teleop side, defined once.

Why this module exists: hand tracking arrives in the OpenXR/WebXR convention (right-handed,
+Y up, −Z forward, quaternions xyzw) while everything downstream (retargeting, the MuJoCo scene,
recordings) uses the MuJoCo world (right-handed, +Z up, quaternions wxyz). Mixing the two is the
classic silent bug of teleop code, so the conversion is a single named constant applied once, at
ingest, by the functions below — and nowhere else.

The mapping (``XR_TO_MUJOCO``, a proper rotation, det +1):

    x_mj = −z_xr    (the viewer's forward becomes MuJoCo +X)
    y_mj = −x_xr    (the viewer's left becomes MuJoCo +Y)
    z_mj = +y_xr    (up stays up)

so a point 1 m in front of the viewer, (0, 0, −1) in XR, is (1, 0, 0) in MuJoCo, and the XR
floor plane y_xr = 0 is the MuJoCo plane z = 0 (``local-floor`` keeps heights meaningful).

Orientations are changed by conjugation, R_mj = C R_xr Cᵀ (q_mj = q_C ⊗ q_xr ⊗ q_C*). That maps
the world *and* re-expresses every body's local axes with the same map, so composing poses
commutes with the conversion (convert-then-compose equals compose-then-convert). For OpenXR hand
joints (local −Z along the bone towards the fingertip, +Y out of the back of the hand) the
converted joint frames therefore have local +X pointing distally along the bone and local +Z
out of the back of the hand (dorsal); local +Y completes the right-handed frame.

Quaternion order is in every name: ``*_wxyz`` is scalar-first (MuJoCo, dexaug internals),
``*_xyzw`` scalar-last (OpenXR, WebXR, Foxglove, the wire format). Poses are pairs
(position (...,3) metres, quaternion (...,4)); every function broadcasts over leading dims.
Reordering a quaternion between the two orders is :func:`sim.transforms.quat_xyzw_to_wxyz` /
:func:`sim.transforms.quat_wxyz_to_xyzw`.
"""

from __future__ import annotations

import numpy as np

from sim import transforms

__all__ = ["MUJOCO_TO_XR", "XR_TO_MUJOCO", "XR_TO_MUJOCO_QUAT_WXYZ", "mujoco_to_xr_positions",
           "mujoco_to_xr_quat_xyzw", "quat_normalize_wxyz", "xr_to_mujoco_pose",
           "xr_to_mujoco_positions", "xr_to_mujoco_quat_wxyz"]

Array = np.ndarray

#: Rotation matrix taking XR reference-space coordinates (+Y up, −Z forward) to MuJoCo world
#: coordinates (+Z up, +X forward): ``p_mj = XR_TO_MUJOCO @ p_xr``.
XR_TO_MUJOCO: Array = np.array([[0.0, 0.0, -1.0],
                                [-1.0, 0.0, 0.0],
                                [0.0, 1.0, 0.0]])
XR_TO_MUJOCO.setflags(write=False)

#: The inverse map (its transpose), for sending poses back to a headset.
MUJOCO_TO_XR: Array = XR_TO_MUJOCO.T.copy()
MUJOCO_TO_XR.setflags(write=False)

#: ``XR_TO_MUJOCO`` as a unit quaternion, wxyz: (0.5, 0.5, −0.5, −0.5).
XR_TO_MUJOCO_QUAT_WXYZ: Array = transforms.mat_to_quat(XR_TO_MUJOCO)
XR_TO_MUJOCO_QUAT_WXYZ.setflags(write=False)


# --- quaternion normalisation for tracking input (products and poses: sim.transforms) ------------


def quat_normalize_wxyz(q_wxyz: Array) -> Array:
    """Unit quaternions; zero or non-finite inputs come back as NaN (never a silent identity),
    so a caller can mark them invalid."""
    q = np.asarray(q_wxyz, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 1e-12, q / np.where(n > 0, n, 1.0), np.nan)


# --- XR ↔ MuJoCo --------------------------------------------------------------------------------


def xr_to_mujoco_positions(p_xr: Array) -> Array:
    """Positions or direction vectors (...,3), metres, from the XR reference space to the MuJoCo
    world."""
    return np.asarray(p_xr, dtype=float) @ XR_TO_MUJOCO.T


def mujoco_to_xr_positions(p_mj: Array) -> Array:
    """Inverse of :func:`xr_to_mujoco_positions`."""
    return np.asarray(p_mj, dtype=float) @ MUJOCO_TO_XR.T


def xr_to_mujoco_quat_wxyz(q_xyzw: Array) -> Array:
    """Orientations (...,4) given xyzw in the XR convention → wxyz in the MuJoCo convention,
    by conjugation (R' = C R Cᵀ; see the module docstring for what happens to local axes)."""
    q = transforms.quat_xyzw_to_wxyz(np.asarray(q_xyzw, dtype=float))
    return transforms.quat_mul(transforms.quat_mul(XR_TO_MUJOCO_QUAT_WXYZ, q),
                         transforms.quat_conj(XR_TO_MUJOCO_QUAT_WXYZ))


def mujoco_to_xr_quat_xyzw(q_wxyz: Array) -> Array:
    """Inverse of :func:`xr_to_mujoco_quat_wxyz`: MuJoCo wxyz → XR xyzw."""
    q = transforms.quat_mul(transforms.quat_mul(transforms.quat_conj(XR_TO_MUJOCO_QUAT_WXYZ), q_wxyz),
                      XR_TO_MUJOCO_QUAT_WXYZ)
    return transforms.quat_wxyz_to_xyzw(q)


def xr_to_mujoco_pose(p_xr: Array, q_xyzw: Array) -> tuple[Array, Array]:
    """A pose (position metres, quaternion xyzw) in XR → (position, quaternion wxyz) in MuJoCo."""
    return xr_to_mujoco_positions(p_xr), xr_to_mujoco_quat_wxyz(q_xyzw)

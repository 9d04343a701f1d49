"""Rigid-body transforms on NumPy arrays, batched over leading dimensions.

Quaternions are scalar-first (w, x, y, z), MuJoCo's order, everywhere inside dexaug; functions
that take or return another order say so in their name. Positions are metres, angles radians.
A pose is a pair (position (...,3), quaternion wxyz (...,4)); rotation matrices are (...,3,3).
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import ArrayLike

Array = np.ndarray


def quat_normalize(q: Array) -> Array:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_mul(a: Array, b: Array) -> Array:
    """Hamilton product a ⊗ b (apply b first, then a, as rotations)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def quat_conj(q: Array) -> Array:
    """Conjugate: the inverse rotation of a unit quaternion."""
    return np.asarray(q, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_to_mat(q: Array) -> Array:
    """Rotation matrices (...,3,3) of unit quaternions (...,4) wxyz."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], axis=-1).reshape(*q.shape[:-1], 3, 3)


def mat_to_quat(m: Array) -> Array:
    """Unit quaternions wxyz (...,4) with w >= 0 of rotation matrices (...,3,3) (Shepperd's
    method, stable for every rotation)."""
    m = np.asarray(m, dtype=float)
    flat = m.reshape(-1, 3, 3)
    out = np.empty((flat.shape[0], 4))
    tr = np.trace(flat, axis1=1, axis2=2)
    diag = np.stack([tr, flat[:, 0, 0], flat[:, 1, 1], flat[:, 2, 2]], axis=1)
    k = np.argmax(diag, axis=1)
    for case in range(4):
        sel = k == case
        if not sel.any():
            continue
        r = flat[sel]
        if case == 0:
            s = 2.0 * np.sqrt(1.0 + tr[sel])
            q = [0.25 * s, (r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s,
                 (r[:, 1, 0] - r[:, 0, 1]) / s]
        else:
            i = case - 1
            j, k2 = (i + 1) % 3, (i + 2) % 3
            s = 2.0 * np.sqrt(1.0 + r[:, i, i] - r[:, j, j] - r[:, k2, k2])
            q = [None] * 4
            q[0] = (r[:, k2, j] - r[:, j, k2]) / s
            q[1 + i] = 0.25 * s
            q[1 + j] = (r[:, j, i] + r[:, i, j]) / s
            q[1 + k2] = (r[:, k2, i] + r[:, i, k2]) / s
        out[sel] = np.stack(q, axis=1)
    out *= np.where(out[:, :1] < 0, -1.0, 1.0)
    return out.reshape(*m.shape[:-2], 4)


def axis_angle_to_quat(axis: Array, angle: Array) -> Array:
    """Quaternions wxyz for rotations by ``angle`` (radians, (...)) about unit ``axis`` (...,3)."""
    half = 0.5 * np.asarray(angle)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)


def cross(a: Array, b: Array) -> Array:
    """a × b over the last axis (broadcasting). Written out because ``np.cross`` spends ~20x
    longer on argument handling than on arithmetic for the single vectors of the simulation
    loops (the validator calls this thousands of times per grasp)."""
    a1, a2, a3 = a[..., 0], a[..., 1], a[..., 2]
    b1, b2, b3 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1], axis=-1)


def rotate(q: Array, v: Array) -> Array:
    """Rotate vectors v (...,3) by unit quaternions q (...,4) wxyz, without forming matrices:
    v' = v + w·t + u × t with t = 2 u × v."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    u = q[..., 1:]
    t = 2.0 * cross(u, v)
    return v + q[..., :1] * t + cross(u, t)


def pose_mul(p_a: Array, q_a: Array, p_b: Array, q_b: Array) -> tuple[Array, Array]:
    """Compose poses: T_a ∘ T_b (b expressed in a's frame)."""
    return np.asarray(p_a, dtype=float) + rotate(q_a, p_b), quat_mul(q_a, q_b)


def pose_inv(p: Array, q: Array) -> tuple[Array, Array]:
    qi = quat_conj(q)
    return -rotate(qi, p), qi


def quat_angle(q_a: Array, q_b: Array) -> Array:
    """Rotation angle (radians, in [0, π]) between two orientations."""
    d = np.abs(np.sum(q_a * q_b, axis=-1))
    return 2.0 * np.arccos(np.clip(d, -1.0, 1.0))


# --- batched rotation matrices (FSG, the synthetic operator) -----------------------------------


def _skew(v: Array) -> Array:
    """Cross-product matrices [v]× (...,3,3) of vectors v (...,3)."""
    k = np.zeros((*v.shape[:-1], 3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return k


def axis_angle_to_mat(axis: Array, angle: Array) -> Array:
    """(B,3,3) rotations by ``angle`` (B,) radians about unit ``axis`` (B,3) (Rodrigues)."""
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    kx = _skew(np.asarray(axis, dtype=float))
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def rotvec_to_mat(rotvecs: Array) -> Array:
    """Rotation matrices (...,3,3) of rotation vectors (...,3) (axis × angle, radians); the
    zero vector gives the identity."""
    v = np.asarray(rotvecs, dtype=float)
    th = np.linalg.norm(v, axis=-1)[..., None, None]
    k = _skew(v)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(th > 1e-12, np.sin(th) / np.where(th > 0, th, 1.0), 1.0)
        c = np.where(th > 1e-12, (1.0 - np.cos(th)) / np.where(th > 0, th * th, 1.0), 0.5)
    return np.eye(3) + s * k + c * (k @ k)


def rotation_between(a: Array, b: Array) -> Array:
    """(B,3,3) rotations taking unit vectors a (B,3) onto unit vectors b (B,3); for a = −b a
    half turn about an axis perpendicular to a."""
    v = np.cross(a, b)
    c = np.einsum("ij,ij->i", a, b)
    vx = _skew(v)
    anti = c < -1 + 1e-9
    k = np.where(anti, 0.0, 1.0 / np.maximum(1.0 + c, 1e-12))
    r = np.eye(3) + vx + vx @ vx * k[:, None, None]
    if anti.any():
        e1, _ = perpendicular_basis(a[anti])
        r[anti] = 2 * e1[:, :, None] * e1[:, None, :] - np.eye(3)
    return r


def perpendicular_basis(n: Array) -> tuple[Array, Array]:
    """Two unit vectors (B,3) completing unit normals n (B,3) to a right-handed basis
    (e1, e2, n)."""
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(n, e1)


def frame_from_x(x: Array, z_hint: Array) -> Array:
    """Right-handed frame (3×3, columns x, y, z) with x along ``x`` and z as close to
    ``z_hint`` as is perpendicular to x."""
    x = np.asarray(x, dtype=float) / np.linalg.norm(x)
    z = np.asarray(z_hint, dtype=float) - (np.dot(z_hint, x)) * x
    z /= np.linalg.norm(z)
    return np.column_stack([x, np.cross(z, x), z])


def slerp_mat(r0: Array, r1: Array, s: float) -> Array:
    """Rotation (3×3) a fraction ``s`` of the way from r0 to r1 along the geodesic."""
    q0, q1 = mat_to_quat(r0), mat_to_quat(r1)
    if float(q0 @ q1) < 0.0:
        q1 = -q1
    d = float(np.clip(q0 @ q1, -1.0, 1.0))
    if d > 0.9995:
        q = q0 + s * (q1 - q0)
    else:
        th = np.arccos(d)
        q = (np.sin((1 - s) * th) * q0 + np.sin(s * th) * q1) / np.sin(th)
    return quat_to_mat(q / np.linalg.norm(q))


def rpy_deg_to_quat(rpy_deg: ArrayLike) -> Array:
    """Rotation about fixed x, then y, then z (degrees, (3,)) as a wxyz quaternion."""
    rx, ry, rz = np.deg2rad(np.asarray(rpy_deg, dtype=float))
    qx = axis_angle_to_quat(np.array([1.0, 0.0, 0.0]), rx)
    qy = axis_angle_to_quat(np.array([0.0, 1.0, 0.0]), ry)
    qz = axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), rz)
    return quat_mul(qz, quat_mul(qy, qx))


def rpy_deg_to_mat(rpy_deg: ArrayLike) -> Array:
    """Rotation about fixed x, then y, then z (degrees, (3,)) as a 3×3 matrix."""
    return quat_to_mat(rpy_deg_to_quat(rpy_deg))


# --- quaternion order at the boundaries (OpenXR, WebXR and Foxglove use xyzw) ------------------


def quat_xyzw_to_wxyz(q_xyzw: Array) -> Array:
    """Reorder scalar-last quaternions (...,4) to scalar-first (a copy)."""
    return np.asarray(q_xyzw)[..., [3, 0, 1, 2]]


def quat_wxyz_to_xyzw(q_wxyz: Array) -> Array:
    """Reorder scalar-first quaternions (...,4) to scalar-last (a copy)."""
    return np.asarray(q_wxyz)[..., [1, 2, 3, 0]]


# --- single poses on the per-frame paths (MuJoCo's C helpers: no batching overhead) ------------


def quat_to_mat1(q_wxyz: Array) -> Array:
    """3×3 rotation of one unit quaternion (wxyz), via MuJoCo (cheaper than
    :func:`quat_to_mat` for one)."""
    out = np.empty(9)
    mujoco.mju_quat2Mat(out, np.ascontiguousarray(q_wxyz, dtype=float))
    return out.reshape(3, 3)


def pose_mul1(p_a: Array, r_a: Array, q_a: Array, p_b: Array, q_b: Array) -> tuple[Array, Array]:
    """T_a ∘ T_b for single poses, with ``r_a`` (q_a's matrix) already at hand."""
    q = np.empty(4)
    mujoco.mju_mulQuat(q, q_a, q_b)
    return p_a + r_a @ p_b, q

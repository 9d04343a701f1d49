"""Rigid-body transforms on NumPy arrays, batched over leading dimensions.

Quaternions are scalar-first (w, x, y, z), MuJoCo's order, everywhere inside dexaug; functions
that take or return another order say so in their name. Positions are metres, angles radians.
A pose is a pair (position (...,3), quaternion wxyz (...,4)); rotation matrices are (...,3,3).
"""

from __future__ import annotations

import numpy as np

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

"""Quaternion helpers for the scene layer, in numpy (the Taichi ones live in ``math3d``).

Quaternions are (w, x, y, z), as everywhere in the sandbox. Every function takes
a single quaternion of shape (4,) or a batch of shape (N, 4).
"""

from __future__ import annotations

import numpy as np

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion: (4,) -> (3, 3) or (N, 4) -> (N, 3, 3)."""
    q = np.asarray(q, dtype=np.float64)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - w * z)
    m[..., 0, 2] = 2 * (x * z + w * y)
    m[..., 1, 0] = 2 * (x * y + w * z)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - w * x)
    m[..., 2, 0] = 2 * (x * z - w * y)
    m[..., 2, 1] = 2 * (y * z + w * x)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def quat_mul(a, b) -> np.ndarray:
    """Hamilton product a * b (apply b first, then a)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` rotations drawn uniformly from SO(3) (normalised 4-D Gaussians), shape (n, 4), w >= 0."""
    q = rng.standard_normal((n, 4))
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    # a zero 4-D Gaussian has probability zero; guard anyway so the result is always unit
    q = np.where(norm > 1e-12, q / np.maximum(norm, 1e-12), IDENTITY)
    return np.where(q[:, :1] < 0, -q, q)

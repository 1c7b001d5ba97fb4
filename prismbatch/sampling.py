"""Seeded random pose generators shared by the demo, benchmarks and tests.

All generators return ``(pos_a, rot_a, pos_b, rot_b)`` as ``(N, 3)`` and
``(N, 3, 3)`` float64 arrays and take a :class:`numpy.random.Generator`.
"""

from __future__ import annotations

import numpy as np

from .geometry import AXIS_DOWN, rotation_with_axis

__all__ = [
    "random_rotations",
    "spins_about_z",
    "rotation_with_axis",
    "tilted_up",
    "facing_poses",
    "free_poses",
    "DISTRIBUTIONS",
    "AXIS_DOWN",
]


def random_rotations(n, rng):
    """``n`` rotations uniform on SO(3) (normalised Gaussian quaternions)."""
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    R = np.empty((n, 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def spins_about_z(phi):
    """Rotations (k, 3, 3) by the angles ``phi`` (k,) about the z axis."""
    c, s = np.cos(phi), np.sin(phi)
    Z = np.zeros((len(phi), 3, 3))
    Z[:, 0, 0] = c
    Z[:, 0, 1] = -s
    Z[:, 1, 0] = s
    Z[:, 1, 1] = c
    Z[:, 2, 2] = 1.0
    return Z


def tilted_up(n, max_tilt, rng):
    """Rotations whose z axis is within ``max_tilt`` radians of +z, random spin."""
    tilt = max_tilt * np.sqrt(rng.uniform(0.0, 1.0, n))  # uniform over the cap (small angles)
    az = rng.uniform(0.0, 2 * np.pi, n)
    spin = rng.uniform(0.0, 2 * np.pi, n)
    # axis of the tilt, horizontal, perpendicular to the azimuth
    kx, ky = -np.sin(az), np.cos(az)
    c, s = np.cos(tilt), np.sin(tilt)
    # Rodrigues rotation about (kx, ky, 0) by tilt
    T = np.empty((n, 3, 3))
    T[:, 0, 0] = c + kx * kx * (1 - c)
    T[:, 0, 1] = kx * ky * (1 - c)
    T[:, 0, 2] = ky * s
    T[:, 1, 0] = kx * ky * (1 - c)
    T[:, 1, 1] = c + ky * ky * (1 - c)
    T[:, 1, 2] = -kx * s
    T[:, 2, 0] = -ky * s
    T[:, 2, 1] = kx * s
    T[:, 2, 2] = c
    return T @ spins_about_z(spin)


def facing_poses(n, rng, *, radius=2.5, max_tilt=np.radians(15.0)):
    """The paper's scene: a at the origin with its axis down, b above it facing it.

    b's axis is within ``max_tilt`` of +z; its end-face centre is uniform in
    ``|x|, |y| <= 2.4 radius`` and ``z in [-0.6 radius, 1.2 radius]``, so the
    set mixes every facing case (1, 2-6 near contact, 5 far away).
    """
    pos_a = np.zeros((n, 3))
    rot_a = np.broadcast_to(AXIS_DOWN, (n, 3, 3)).copy()
    pos_b = np.column_stack(
        [rng.uniform(-2.4 * radius, 2.4 * radius, (n, 2)), rng.uniform(-0.6 * radius, 1.2 * radius, n)]
    )
    return pos_a, rot_a, pos_b, tilted_up(n, max_tilt, rng)


def free_poses(n, rng, *, radius=2.5):
    """Uniform random rotations for both; centres uniform in a box of half-width 2 radius."""
    pos_a = rng.uniform(-2 * radius, 2 * radius, (n, 3))
    pos_b = rng.uniform(-2 * radius, 2 * radius, (n, 3))
    return pos_a, random_rotations(n, rng), pos_b, random_rotations(n, rng)


DISTRIBUTIONS = {"facing": facing_poses, "free": free_poses}

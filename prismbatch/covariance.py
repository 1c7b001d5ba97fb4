"""Pose-noise covariances for :func:`~prismbatch.collision_probability`: checked and factored.

A covariance (6x6: translation then rotation, world frame) is factored as ``cov = L L^T`` through the
eigen-decomposition of its correlation matrix: translation and rotation have different units, and a cut
relative to the largest variance would drop a small body's translations. Eigenvalues below
:data:`EIG_RTOL` of the largest are dropped, so singular and rotation-free covariances need no special
case.
"""

from __future__ import annotations

import numpy as np

from .checks import as_real_array

__all__ = ["noise_factor", "rotation_free", "EIG_RTOL", "SYM_RTOL", "PSD_RTOL"]

#: Eigenvalues of the correlation matrix below this fraction of the largest count as 0.
EIG_RTOL = 1e-12
#: Asymmetry tolerated, relative to the standard deviations' product.
SYM_RTOL = 1e-9
#: Negative eigenvalues tolerated, relative to the largest.
PSD_RTOL = 1e-9


def noise_factor(cov, name, n):
    """``(n, 6, 6)`` factors L with ``L L^T = cov`` (zero columns where the covariance is singular)."""
    c = as_real_array(cov, name).astype(np.float64)
    if c.shape not in ((6, 6), (n, 6, 6)):
        raise ValueError(f"{name} has shape {c.shape}; expected (6, 6) or (N, 6, 6) with N = {n} queries")
    batched = c.ndim == 3
    c = c.reshape(-1, 6, 6)
    where = lambda i: f"{name}[{i}]" if batched else name  # noqa: E731
    finite = np.isfinite(c).all(axis=(1, 2))
    if not finite.all():
        raise ValueError(f"{where(int(np.argmin(finite)))} has non-finite entries")
    var = np.diagonal(c, axis1=1, axis2=2)
    bad = (var < 0).any(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{where(i)} is not positive semidefinite (variance {var[i].min():.3g} on its diagonal)")
    # Tolerances apply to the correlation matrix: translation and rotation have different units,
    # and a cut relative to the largest variance would drop a small body's translations.
    scale = np.sqrt(np.where(var > 0, var, 1.0))
    r = c / scale[:, :, None] / scale[:, None, :]
    asym = np.abs(r - r.transpose(0, 2, 1)).max(axis=(1, 2))
    bad = asym > SYM_RTOL
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"{where(i)} is not symmetric (max |C - C^T| = {asym[i]:.3g} of the standard deviations' product)"
        )
    lam, V = np.linalg.eigh(0.5 * (r + r.transpose(0, 2, 1)))
    top = np.maximum(lam[:, -1], 0.0)
    bad = lam[:, 0] < -PSD_RTOL * top - 1e-300
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"{where(i)} is not positive semidefinite (its correlation matrix has eigenvalue {lam[i, 0]:.3g})"
        )
    lam = np.where(lam > EIG_RTOL * top[:, None], lam, 0.0)
    L = scale[:, :, None] * V * np.sqrt(lam)[:, None, :]
    if L.shape[0] != n:
        L = np.broadcast_to(L, (n, 6, 6))
    # Writeable (a broadcast view is read-only, and Numba compiles the sampling loops again for that)
    return np.require(L, requirements=("C", "W"))


def rotation_free(cov):
    """True if the covariance has no rotational noise (its lower-right 3x3 block is 0)."""
    return not np.any(np.asarray(cov, dtype=np.float64)[..., 3:, 3:])

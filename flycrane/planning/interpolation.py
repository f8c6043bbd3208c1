"""Interpolation between configurations: the one local path of every planner and checker.

Positions and the tilt theta interpolate linearly; phi, sigma and the alphas are angles on
the circle and interpolate the short way round, results wrapped into (-pi, pi].
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Columns of q that are angles on the circle (phi, sigma, alpha1..3); theta is not: it lives
#: in [0, pi] and never wraps.
CIRCULAR = np.array([3, 5, 6, 7, 8])


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped into (-pi, pi]."""
    wrapped = np.remainder(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi
    return np.where(wrapped == -np.pi, np.pi, wrapped)


def configuration_difference(q_from: ArrayLike, q_to: ArrayLike) -> NDArray[np.float64]:
    """Shortest displacement from q_from to q_to, shape broadcast of both (..., 9)."""
    delta = np.asarray(q_to, dtype=float) - np.asarray(q_from, dtype=float)
    delta[..., CIRCULAR] = wrap_angle(delta[..., CIRCULAR])
    return delta


def interpolate(q_from: ArrayLike, q_to: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
    """Configurations at fractions t of the local path from q_from to q_to.

    Parameters
    ----------
    q_from, q_to : array-like, shape (9,) or (N, 9)
    t : array-like, shape (K,) or scalar
        Fractions in [0, 1]; t = 0 gives q_from and t = 1 gives q_to (angles wrapped).

    Returns
    -------
    q : ndarray, shape (K, 9) for single configurations, or broadcast (N, 9) with (N,) t.
    """
    q_from = np.asarray(q_from, dtype=float)
    t = np.asarray(t, dtype=float)
    if q_from.ndim == 1 and t.ndim == 1:
        t = t[:, None]
    elif t.ndim >= 1:
        t = t[..., None]
    result = q_from + t * configuration_difference(q_from, q_to)
    result[..., CIRCULAR] = wrap_angle(result[..., CIRCULAR])
    return result

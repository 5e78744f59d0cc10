"""Real root of a cubic nearest to a guess, polished by Newton steps."""

from __future__ import annotations

import math

import numba
import numpy as np

from .._typing import FloatArray

__all__ = ["cubic_root_near"]


@numba.njit(cache=True)
def _newton(p0, p1, p2, p3, t, steps, rtol):  # noqa: ANN001, ANN202 # pragma: no cover
    """At most ``steps`` Newton steps on the cubic from ``t``: (root, converged to ``rtol``)."""
    for _ in range(steps):
        f = p0 + t * (p1 + t * (p2 + t * p3))
        df = p1 + t * (2 * p2 + 3 * t * p3)
        if df == 0 or not np.isfinite(df):
            return t, False
        step = f / df
        t -= step
        if abs(step) <= rtol * max(1.0, abs(t)):
            return t, True
    return t, False


def cubic_root_near(c: FloatArray, target: float, guess: float) -> float:
    """Solve ``c0 + c1 t + c2 t^2 + c3 t^3 = target`` for the real root nearest ``guess``.

    Parameters
    ----------
    c : (4,) float64 array
        Coefficients in increasing degree.
    target : float
        Right-hand side.
    guess : float
        The root closest to this is returned.

    Returns
    -------
    float
        The root (``nan`` when the polynomial is constant or not finite).
    """
    c0, p1, p2, p3 = (float(v) for v in c)
    p0 = c0 - target
    if not all(map(math.isfinite, (p0, p1, p2, p3))) or max(abs(p1), abs(p2), abs(p3)) == 0:
        return float("nan")
    # Newton from the guess: the volume correction is a small, simple root
    t, ok = _newton(p0, p1, p2, p3, float(guess), 30, 1e-15)
    if ok:
        return t
    p = np.array([p0, p1, p2, p3])
    roots = np.roots(p[::-1])
    real = roots[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots))].real
    if len(real) == 0:
        real = roots.real
    t = float(real[np.argmin(np.abs(real - guess))])
    return _newton(p0, p1, p2, p3, t, 3, 1e-16)[0]  # polish to full precision

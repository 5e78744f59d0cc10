"""Real root of a cubic nearest to a guess, polished by Newton steps."""

from __future__ import annotations

import math

import numba
import numpy as np

from .._typing import FloatArray

__all__ = ["cubic_root_near"]


@numba.njit(cache=True)
def _newton(p0, p1, p2, p3, t):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    """Newton's method on the cubic from ``t``: (root, converged)."""
    for _ in range(30):
        f = p0 + t * (p1 + t * (p2 + t * p3))
        df = p1 + t * (2 * p2 + 3 * t * p3)
        if df == 0 or not np.isfinite(df):
            return t, False
        step = f / df
        t -= step
        if abs(step) <= 1e-15 * max(1.0, abs(t)):
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
    t, ok = _newton(p0, p1, p2, p3, float(guess))
    if ok:
        return t
    p = np.array([p0, p1, p2, p3])
    roots = np.roots(p[::-1])
    real = roots[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots))].real
    if len(real) == 0:
        real = roots.real
    t = float(real[np.argmin(np.abs(real - guess))])
    for _ in range(3):  # Newton polish to full precision
        f = p[0] + t * (p[1] + t * (p[2] + t * p[3]))
        df = p[1] + t * (2 * p[2] + 3 * t * p[3])
        if df == 0:
            break
        step = f / df
        t -= step
        if abs(step) <= 1e-16 * max(1.0, abs(t)):
            break
    return t

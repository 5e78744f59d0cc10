"""Real root of a cubic nearest to a guess, polished by Newton steps."""

from __future__ import annotations

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


@numba.njit(cache=True)
def root_near(p0, p1, p2, p3, guess):  # noqa: ANN001, ANN201 # pragma: no cover - compiled
    """Real root of ``p0 + p1 t + p2 t^2 + p3 t^3`` nearest ``guess``, compiled.

    See `cubic_root_near`; ``nan`` for a constant or non-finite polynomial.
    """
    if not (np.isfinite(p0) and np.isfinite(p1) and np.isfinite(p2) and np.isfinite(p3)):
        return np.nan
    if max(abs(p1), abs(p2), abs(p3)) == 0:
        return np.nan
    # Newton from the guess: the volume correction is a small, simple root
    t, ok = _newton(p0, p1, p2, p3, guess, 30, 1e-15)
    if ok:
        return t
    # otherwise all roots (companion matrix), the real one nearest the guess; complex
    # input, as compiled eigenvalues of a real matrix may not turn complex
    if p3 != 0:
        roots = np.roots(np.array([p3, p2, p1, p0], dtype=np.complex128))
    elif p2 != 0:
        roots = np.roots(np.array([p2, p1, p0], dtype=np.complex128))
    else:
        return -p0 / p1
    best, best_d, best_any, best_any_d = np.nan, np.inf, np.nan, np.inf
    for r in roots:
        d = abs(r.real - guess)
        if abs(r.imag) <= 1e-9 * max(1.0, abs(r)) and d < best_d:
            best, best_d = r.real, d
        if d < best_any_d:
            best_any, best_any_d = r.real, d
    t = best if best_d < np.inf else best_any
    return _newton(p0, p1, p2, p3, t, 3, 1e-16)[0]  # polish to full precision


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
    return float(root_near(c0 - target, p1, p2, p3, float(guess)))

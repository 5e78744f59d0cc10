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
def _eval(p0, p1, p2, p3, t):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    return p0 + t * (p1 + t * (p2 + t * p3))


@numba.njit(cache=True)
def _bracketed(p0, p1, p2, p3, lo, hi):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    """The root in ``[lo, hi]`` where the cubic changes sign: Newton kept in the bracket.

    Where a Newton step would leave the bracket, or shrink it too slowly, it
    bisects instead (Numerical Recipes' ``rtsafe``); to full precision.
    """
    flo = _eval(p0, p1, p2, p3, lo)
    if flo == 0:
        return lo
    if _eval(p0, p1, p2, p3, hi) == 0:
        return hi
    t = 0.5 * (lo + hi)
    for _ in range(200):
        f = _eval(p0, p1, p2, p3, t)
        if f == 0:
            return t
        if (f < 0) == (flo < 0):
            lo, flo = t, f
        else:
            hi = t
        df = p1 + t * (2.0 * p2 + 3.0 * t * p3)
        nt = t - f / df if df != 0 else 0.5 * (lo + hi)
        if not (lo < nt < hi) or not np.isfinite(nt):
            nt = 0.5 * (lo + hi)
        if nt == t or hi - lo <= 4e-16 * max(abs(lo), abs(hi)):
            return nt
        t = nt
    return t


@numba.njit(cache=True)
def _real_roots(p0, p1, p2, p3):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    """Real roots of ``p0 + p1 t + p2 t^2 + p3 t^3`` (nan where there are fewer than three).

    The derivative's roots split the line into at most three intervals where
    the polynomial is monotone; within the root bound ``1 + max |p_i / p_3|``
    (Cauchy) each interval with a sign change holds exactly one root, found by
    safeguarded Newton steps. Accurate where the roots differ by orders of
    magnitude (closed forms lose the small ones there); a root of even
    multiplicity counts only where the polynomial vanishes exactly. Scalars
    only, so nothing here compiles NumPy's polynomial or eigenvalue routines.
    """
    out = np.empty(3)
    for i in range(3):
        out[i] = np.nan
    bound = 1.0 + max(abs(p0), abs(p1), abs(p2)) / abs(p3) if p3 != 0 else np.inf
    if not np.isfinite(bound):
        p3 = 0.0  # a leading term too small to matter within floating point range
    if p3 == 0:
        if p2 == 0:
            if p1 != 0:
                out[0] = -p0 / p1
            return out
        disc = p1 * p1 - 4.0 * p2 * p0
        if disc < 0:
            return out
        h = -0.5 * (p1 + (np.sqrt(disc) if p1 >= 0 else -np.sqrt(disc)))
        out[0] = h / p2
        if h != 0:
            out[1] = p0 / h
        return out
    # the derivative p1 + 2 p2 t + 3 p3 t^2: its real roots, ascending, within the bound
    ends = np.empty(4)
    ends[0] = -bound
    k = 1
    disc = 4.0 * p2 * p2 - 12.0 * p3 * p1
    if disc > 0:
        h = -0.5 * (2.0 * p2 + (np.sqrt(disc) if p2 >= 0 else -np.sqrt(disc)))
        c1 = h / (3.0 * p3)
        c2 = p1 / h if h != 0 else c1
        if -bound < min(c1, c2) < bound:
            ends[k] = min(c1, c2)
            k += 1
        if -bound < max(c1, c2) < bound:
            ends[k] = max(c1, c2)
            k += 1
    ends[k] = bound
    n = 0
    for i in range(k):
        lo, hi = ends[i], ends[i + 1]
        flo, fhi = _eval(p0, p1, p2, p3, lo), _eval(p0, p1, p2, p3, hi)
        if (flo <= 0 <= fhi or fhi <= 0 <= flo) and n < 3:
            r = _bracketed(p0, p1, p2, p3, lo, hi)
            if n == 0 or r != out[n - 1]:
                out[n] = r
                n += 1
    return out


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
    # otherwise every real root (closed form), the one nearest the guess
    roots = _real_roots(p0, p1, p2, p3)
    t, best_d = np.nan, np.inf
    for r in roots:
        if np.isfinite(r) and abs(r - guess) < best_d:
            t, best_d = r, abs(r - guess)
    if not np.isfinite(t):
        return np.nan
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

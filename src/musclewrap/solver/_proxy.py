"""Compiled parts of the default per-pose solve: the proxy's fixed point and its products.

A pose of the default solver makes one pass over the fine coordinates ``W`` (`rows_dot`)
and otherwise works with matrices of the cage's and the proxy's size (300 and about 500
rows), where each Python-level step costs as much as its arithmetic. The whole plain
fixed-point iteration on the proxy is therefore one compiled call, and its two products per
iteration run in single precision from float32 copies of the matrices (half the bytes through
the caches). On one thread the compiled products are as fast as numpy's at this size, and
a float32 matrix with double-precision sums, which numpy can only do by copying the matrix
to float64, twice as fast (`python benchmarks/speed/bench_kernels.py`, item 5).
"""

from __future__ import annotations

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ..mesh.kernels import cubic_pair_ser, gradient_kernel, mean_rows_kernel, root_near

__all__ = [
    "PLAIN_CONVERGED",
    "PLAIN_NO_ROOT",
    "PLAIN_SLOW",
    "mat3",
    "plain_iterations",
    "stationary",
]

#: `plain_iterations` outcomes: stationary; too slow or out of iterations (Newton's turn);
#: no finite volume correction.
PLAIN_CONVERGED, PLAIN_SLOW, PLAIN_NO_ROOT = 0, 1, 2


@numba.njit(fastmath=True, cache=True)
def _mat3_kernel(A, XT, out):  # pragma: no cover - compiled
    # out = A @ XT.T for three columns: one contiguous pass over each row of A
    n, m = A.shape
    for r in range(n):
        # sums in A's precision, started from the first term (float32 stays float32)
        a = A[r, 0]
        s0, s1, s2 = a * XT[0, 0], a * XT[1, 0], a * XT[2, 0]
        for j in range(1, m):
            a = A[r, j]
            s0 += a * XT[0, j]
            s1 += a * XT[1, j]
            s2 += a * XT[2, j]
        out[r, 0] = s0
        out[r, 1] = s1
        out[r, 2] = s2


@numba.njit(cache=True)
def _mat3(A, X):  # pragma: no cover - compiled
    XT = np.empty((3, X.shape[0]))
    for i in range(X.shape[0]):
        for k in range(3):
            XT[k, i] = X[i, k]
    out = np.empty((A.shape[0], 3))
    _mat3_kernel(A, XT, out)
    return out


def mat3(A: FloatArray, X: FloatArray) -> FloatArray:
    """``A @ X`` for a small C-contiguous ``A`` and three columns, on one thread.

    Parameters
    ----------
    A : (n, m) float64 or float32 array, C-contiguous
        A matrix of the cage's or the proxy's size.
    X : (m, 3) float64 array
        Positions or directions.

    Returns
    -------
    (n, 3) float64 array
        Summed in double precision.
    """
    return _mat3(A, np.ascontiguousarray(X, dtype=np.float64))


@numba.njit(cache=True)
def stationary(step, prev_step, its, size, floor, tol_dir):  # noqa: ANN001, ANN201 # pragma: no cover
    """Whether a linearly converging fixed point has settled, and its observed rate.

    With rate ``rho`` = step / previous step, the distance to the limit is at most
    ``rho / (1 - rho) * step`` (a posteriori bound); it must be below ``tol_dir`` of the
    correction's size (at least ``floor``). The first step (from ``x_ls``) is the whole
    correction, so ``rho`` needs two more. Serves the default and the exact iteration.
    """
    rho = step / prev_step if its >= 3 and prev_step > 0 else 1.0
    error = step * rho / (1.0 - rho) if rho < 0.5 else step
    return error <= tol_dir * max(size, floor), rho


#: plain iterations before their rate is judged for Newton's method
_NEWTON_AFTER = 4


@numba.njit(cache=True)
def _plain_iterations(P_ls, Wd, B, Fd, Vd0, plain, tol_dir, floor, rate):  # pragma: no cover
    n, m = Wd.shape
    XU = np.empty((n, 6))  # [P_ls, P_u]: the proxy's volume along -P_u is a cubic
    # (element loops rather than slice assignments here and below: those compile a
    # shape check with string formatting that costs seconds on a first run)
    for i in range(n):
        for k in range(3):
            XU[i, k] = P_ls[i, k]
    P = P_ls.copy()
    g = gradient_kernel(P, Fd, mean_rows_kernel(P))
    gT = np.empty((3, n), dtype=B.dtype)
    uT = np.empty((3, m), dtype=B.dtype)
    u = np.empty((m, 3), dtype=B.dtype)
    u_prev = np.empty((m, 3))
    best_u = np.empty((m, 3))
    for j in range(m):
        for k in range(3):
            u_prev[j, k] = best_u[j, k] = 0.0
    Pu = np.empty((n, 3), dtype=B.dtype)
    lam, prev_step = 0.0, 0.0
    best_e, best_lam = np.inf, 0.0
    status, its = PLAIN_SLOW, 0
    for its in range(1, plain + 1):
        for i in range(n):
            for k in range(3):
                gT[k, i] = g[i, k]
        _mat3_kernel(B, gT, u)  # u = H^-1 Wd^T g, the cage direction
        for j in range(m):
            for k in range(3):
                uT[k, j] = u[j, k]
        _mat3_kernel(Wd, uT, Pu)  # its proxy image
        for i in range(n):
            for k in range(3):
                XU[i, 3 + k] = Pu[i, k]
        c = cubic_pair_ser(XU, Fd)
        lam_new = root_near(c[0] - Vd0, c[1], c[2], c[3], lam)
        if not np.isfinite(lam_new):
            status = PLAIN_NO_ROOT
            break
        step, size = 0.0, 0.0
        for j in range(m):
            for k in range(3):
                # cage step |x_new - x| = |lam_new u - lam u_prev|; size of the correction
                step = max(step, abs(lam_new * u[j, k] - lam * u_prev[j, k]))
                size = max(size, abs(lam_new * u[j, k]))
                u_prev[j, k] = u[j, k]
        gu = 0.0
        for i in range(n):
            for k in range(3):
                P[i, k] = P_ls[i, k] - lam_new * XU[i, 3 + k]
                gu += g[i, k] * XU[i, 3 + k]
        lam = lam_new
        # energy of this iterate, (x - x_ls)^T H (x - x_ls) = lam^2 u^T H u = lam^2 g . P_u
        e = lam * lam * gu
        if e < best_e:
            best_e, best_lam = e, lam
            for j in range(m):
                for k in range(3):
                    best_u[j, k] = u_prev[j, k]
        done, rho = stationary(step, prev_step, its, size, floor, tol_dir)
        prev_step = step
        if done:
            status = PLAIN_CONVERGED
            break
        if its >= _NEWTON_AFTER and rho > rate:
            break  # too slow or oscillating for plain iteration
        if its < plain:
            g = gradient_kernel(P, Fd, mean_rows_kernel(P))
    return lam, u_prev, its, status, best_lam, best_u


def plain_iterations(
    P_ls: FloatArray,
    Wd: FloatArray,
    B: FloatArray,
    Fd: IntArray,
    Vd0: float,
    *,
    plain: int,
    tol_dir: float,
    floor: float,
    rate: float,
) -> tuple[float, FloatArray, int, int, float, FloatArray]:
    """Fixed point of the least squares constrained to the proxy's rest volume.

    Iterates ``x = x_ls - lam u`` with ``u = H^-1 Wd^T g(Wd x)`` (``g`` the proxy's
    volume gradient) and ``lam`` the root of the proxy volume's cubic along ``-u``
    that keeps the proxy's rest volume ``Vd0``. Only the proxy image ``P = Wd (x - c)``
    is kept; the cage positions follow from the returned ``lam`` and ``u``.

    Parameters
    ----------
    P_ls : (q, 3) float64 array
        Proxy vertices of the unconstrained solution, centred.
    Wd : (q, m) float32 array, C-contiguous
        The proxy's coordinates.
    B : (m, q) float32 array, C-contiguous
        ``H^-1 Wd^T``.
    Fd : (p, 3) int64 array
        Proxy triangles.
    Vd0 : float
        Proxy rest volume.
    plain : int
        Most iterations.
    tol_dir : float
        Stationarity tolerance, relative to the largest cage vertex correction.
    floor : float
        Smallest correction size the tolerance is taken of (a rigid pose has none).
    rate : float
        Observed convergence rate above which the iteration stops for Newton's method
        (judged from the fourth iteration).

    Returns
    -------
    lam : float
        Multiplier of the last iterate.
    u : (m, 3) float64 array
        Its direction: the last iterate is ``x_ls - lam u``.
    iterations : int
    status : int
        `PLAIN_CONVERGED`, `PLAIN_SLOW` or `PLAIN_NO_ROOT`.
    best_lam, best_u : float, (m, 3) float64 array
        The iterate of least energy ``(x - x_ls)^T H (x - x_ls)`` (Newton's start).

    Notes
    -----
    The products run in single precision: they only steer the direction, and the
    fine volume is then corrected exactly along it in double precision. Against the
    same iteration in double precision the mesh moves by at most 2.2e-9 of the
    muscle's size, with the same number of iterations, on the capsule and every VHF
    muscle in the five scenarios (``python benchmarks/accuracy/bench_accuracy.py``); the tests
    assert 1e-8 (``tests/test_solver.py``, ``tests/test_realdata.py``).
    """
    return _plain_iterations(
        np.ascontiguousarray(P_ls, dtype=np.float64),
        Wd,
        B,
        np.ascontiguousarray(Fd, dtype=np.int64),
        float(Vd0),
        int(plain),
        float(tol_dir),
        float(floor),
        float(rate),
    )

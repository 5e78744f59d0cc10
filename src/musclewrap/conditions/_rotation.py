"""Rotation of the Laplacian's differential coordinates by the skeleton's motion."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ._lines import LineError, _arclength, distinct_mask, window_mean

__all__ = [
    "RotationField",
    "SampleRotations",
    "kabsch",
    "matrix_to_quaternion",
    "path_rotations",
    "quaternion_to_matrix",
    "sample_rotations",
]


def kabsch(P: FloatArray, Q: FloatArray) -> tuple[FloatArray, bool]:
    """Best rotation taking centred ``P`` onto centred ``Q`` (least squares).

    Returns
    -------
    R : (3, 3) float64 array
    determined : bool
        False when ``P`` is (nearly) collinear, so the rotation about the line
        is not determined by the points.
    """
    P0 = P - P.mean(axis=0)
    return _best_rotation(P0, Q - Q.mean(axis=0)), not _collinear(P0)


def _collinear(P0: FloatArray) -> bool:
    """True when centred points ``P0`` lie (nearly) on one line (or are fewer than 3)."""
    sv = np.linalg.svd(P0, compute_uv=False)
    return not (len(P0) >= 3 and sv[1] > 1e-6 * sv[0])


def _best_rotation(P0: FloatArray, Q0: FloatArray) -> FloatArray:
    U, _, Vt = np.linalg.svd(P0.T @ Q0)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    return Vt.T @ np.diag([1.0, 1.0, d]) @ U.T


def _tangents(S: FloatArray, line: IntArray) -> FloatArray:
    T = np.empty_like(S)
    _tangents_kernel(np.ascontiguousarray(S, dtype=np.float64), np.asarray(line), T)
    return T


@numba.njit(cache=True)
def _tangents_kernel(S, line, T):  # pragma: no cover - compiled
    # per line: unit segment directions; a sample's tangent is the mean of its two
    # segments (the end segment at the ends; the incoming one at a fold-back)
    k = S.shape[0]
    start = 0
    while start < k:
        end = start
        while end + 1 < k and line[end + 1] == line[start]:
            end += 1
        nseg = end - start
        seg = np.empty((nseg, 3))  # (element arithmetic: quicker to compile on a first run)
        for i in range(nseg):
            d0 = S[start + i + 1, 0] - S[start + i, 0]
            d1 = S[start + i + 1, 1] - S[start + i, 1]
            d2 = S[start + i + 1, 2] - S[start + i, 2]
            r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            seg[i, 0], seg[i, 1], seg[i, 2] = d0 / r, d1 / r, d2 / r
        for i in range(start, end + 1):
            j = i - start
            if j == 0:
                t0, t1, t2 = seg[0, 0], seg[0, 1], seg[0, 2]
            elif j == nseg:
                t0, t1, t2 = seg[nseg - 1, 0], seg[nseg - 1, 1], seg[nseg - 1, 2]
            else:
                t0 = seg[j - 1, 0] + seg[j, 0]
                t1 = seg[j - 1, 1] + seg[j, 1]
                t2 = seg[j - 1, 2] + seg[j, 2]
                if np.sqrt(t0 * t0 + t1 * t1 + t2 * t2) < 1e-9:
                    t0, t1, t2 = seg[j - 1, 0], seg[j - 1, 1], seg[j - 1, 2]
            r = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            T[i, 0], T[i, 1], T[i, 2] = t0 / r, t1 / r, t2 / r
        start = end + 1


def minimal_rotation(a: FloatArray, b: FloatArray) -> FloatArray:
    """(k, 3, 3) rotations taking unit vectors ``a`` to ``b`` about ``a x b``."""
    out = np.empty((len(a), 3, 3))
    _minimal_rotations(np.ascontiguousarray(a), np.ascontiguousarray(b), out)
    return out


@numba.njit(cache=True)
def _minimal_rotations(a, b, out):  # pragma: no cover - compiled
    for i in range(a.shape[0]):
        _minimal_rotation_one(a[i], b[i], out[i])


def sample_rotations(
    rest: FloatArray,
    current: FloatArray,
    line: IntArray,
    *,
    reference_rest: FloatArray | None = None,
    reference_current: FloatArray | None = None,
) -> FloatArray:
    """Rotation of the skeleton at every sample, rest to current pose.

    Each sample gets the frame (tangent, normal towards the reference, binormal)
    in both poses and the rotation between them (section 4.1 of Kohout et
    al. 2012, applied per sample instead of once per muscle, so bends rotate
    each part of the muscle by its own amount).

    Parameters
    ----------
    rest, current : (k, 3) float64 arrays
        Matched samples of all lines.
    line : (k,) int array
        Line index of each sample.
    reference_rest, reference_current : (3,) float64 arrays, optional
        Reference point (e.g. the centroid of the bone the muscle runs along)
        in both poses. Without one, the twist about the line comes from the
        best rigid fit of all samples when the samples are not collinear, and
        otherwise each sample's tangent is turned by the minimal rotation (no
        twist about the line, which a single straight line cannot define).

    Returns
    -------
    (k, 3, 3) float64 array
        Rotations; under a rigid motion of lines and reference point, every
        one equals that motion's rotation.
    """
    return SampleRotations(rest, line, reference_rest=reference_rest)(
        current, reference_current=reference_current
    )


def path_rotations(
    lines: Mapping[str, FloatArray],
    rotations: Mapping[str, FloatArray],
    names: Sequence[str],
    params: Sequence[FloatArray],
    halfwidths: Sequence[FloatArray] | None = None,
    keys: Mapping[str, tuple[FloatArray, FloatArray]] | None = None,
) -> FloatArray:
    """Rotation of every sample from the bodies its path's points are fixed in.

    A sample at normalized arc length ``t`` of a line lies between two of its points;
    its rotation is the spherical interpolation (slerp) of theirs at its place on that
    segment. So a part of the path fixed in one bone turns with that bone, and a segment
    across a joint turns gradually from one bone's rotation to the other's: continuous
    in the pose wherever the path's points are (where a conditional via point switches,
    the path itself has a kink), exact under a rigid motion, and free of the twist
    frame's degeneracy where a reference point lies along the line.

    Parameters
    ----------
    lines : mapping of str to (k, 3) float64 array
        Current lines (repeated consecutive points are dropped, as by `check_lines`).
    rotations : mapping of str to (k, 3, 3) float64 array
        Per line and point, its body's rotation from the rest pose.
    names, params : sequences
        The lines' names and each one's sample parameters (`LineSampling`).
    halfwidths : sequence of (s,) float64 arrays, optional
        Each line's samples' windows (`LineSampling.halfwidths`): a sample's rotation is
        then that of the mean over its window of the points' quaternions joined linearly
        (`musclewrap.conditions.window_mean`), continuously differentiable in the pose
        as the samples' points are.
    keys : mapping of str to ((n,), (n, 3, 3)) float64 arrays, optional
        Per line, rotations at normalized arc lengths to interpolate instead of its
        points' (`PathLines` ``keys``: every point the path is defined by, active or
        not): where a conditional via point switches, the samples' rotations stay
        continuous.

    Returns
    -------
    (count, 3, 3) float64 array

    Raises
    ------
    LineError
        If a line has no rotations, or not one per point.
    """
    out = []
    for i, (n, t) in enumerate(zip(names, params, strict=True)):
        P = np.asarray(lines[n], dtype=np.float64)
        R = rotations.get(n)
        if R is None or np.shape(R) != (len(P), 3, 3) or not np.all(np.isfinite(R)):
            raise LineError(
                f"current lines: line '{n}' needs one finite 3x3 rotation per point "
                f"({len(P)}), got {None if R is None else np.shape(R)}"
            )
        if keys is not None and n in keys:
            # the keys' parameters as a poly-line along x, its arc length theirs
            s, Rk = _key_rotations(*keys[n])
            X = np.zeros((len(s), 3))
            X[:, 0] = s
            q = matrix_to_quaternion(Rk)
        else:
            keep = distinct_mask(P)
            X = P[keep]
            q = matrix_to_quaternion(R[keep])
            s = _arclength(X)
        # each quaternion on its predecessor's side: the interpolation takes the shorter way
        flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0.0, -1.0, 1.0))
        q[1:] *= flip[:, None]
        if halfwidths is not None:
            m = window_mean(X, t, halfwidths[i], q)
            out.append(quaternion_to_matrix(m / np.linalg.norm(m, axis=1)[:, None]))
            continue
        j = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(s) - 2)
        h = s[j + 1] - s[j]
        # a key's own parameter gives its rotation; keys at one parameter: the last's
        f = np.clip((t - s[j]) / np.where(h > 0, h, 1.0), 0.0, 1.0)
        f[h <= 0] = 1.0
        out.append(quaternion_to_matrix(_slerp(q[j], q[j + 1], f)))
    return np.ascontiguousarray(np.concatenate(out))


def _key_rotations(t: FloatArray, R: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Keys as a non-decreasing partition of [0, 1] (`path_rotations`'s ``keys``).

    The first at 0, the last at 1. Keys at one parameter stay (a rotation there steps
    from one to the next): dropping one would make the field jump as another key's
    parameter reaches it (a via point projected past the path's end), where keeping
    both lets it change continuously.
    """
    t = np.clip(np.maximum.accumulate(np.asarray(t, dtype=np.float64)), 0.0, 1.0)
    if len(t) < 2:
        raise LineError(f"a path's rotation keys need two or more, got {len(t)}")
    t[0], t[-1] = 0.0, 1.0
    return t, np.asarray(R, dtype=np.float64)


def _slerp(q0: FloatArray, q1: FloatArray, f: FloatArray) -> FloatArray:
    """Unit quaternions ``f`` of the way from ``q0`` to ``q1`` (rows; linear where equal).

    Not scipy's `Slerp`: per pose and line it cost 467 us against 145 us here (3 lines
    of 40 samples), which took the sweeps' fibres from 1.24x to 1.32x ``--no-fibres``.
    """
    angle = np.arccos(np.clip(np.sum(q0 * q1, axis=1), -1.0, 1.0))
    sin = np.sin(angle)
    far = sin > 1e-9
    a, b = 1.0 - f, f.copy()
    a[far] = np.sin((1.0 - f[far]) * angle[far]) / sin[far]
    b[far] = np.sin(f[far] * angle[far]) / sin[far]
    q = a[:, None] * q0 + b[:, None] * q1
    return q / np.linalg.norm(q, axis=1)[:, None]


class SampleRotations:
    """`sample_rotations` with everything that depends on the rest pose done once.

    Parameters
    ----------
    rest : (k, 3) float64 array
        Rest samples of all lines.
    line : (k,) int array
        Line index of each sample.
    reference_rest : (3,) float64 array, optional
        Rest reference point.
    """

    def __init__(
        self, rest: FloatArray, line: IntArray, *, reference_rest: FloatArray | None = None
    ) -> None:
        self.rest = np.ascontiguousarray(rest, dtype=np.float64)
        self.line = np.asarray(line)
        self.reference_rest = reference_rest
        self.T0 = _tangents(self.rest, self.line)
        self._rest_centred = self.rest - self.rest.mean(axis=0)
        self.collinear = _collinear(self._rest_centred)
        # a reference direction perpendicular to the skeleton's principal axis
        _, _, vt = np.linalg.svd(self._rest_centred)
        self._A0 = np.ascontiguousarray(np.tile(vt[1], (len(rest), 1)))

    def __call__(
        self, current: FloatArray, *, reference_current: FloatArray | None = None
    ) -> FloatArray:
        """(k, 3, 3) rotations of the samples for the current pose."""
        T1 = _tangents(current, self.line)
        if self.reference_rest is not None and reference_current is not None:
            A0 = self.reference_rest[None, :] - self.rest
            A1 = reference_current[None, :] - current
        elif self.collinear:
            return minimal_rotation(self.T0, T1)
        else:
            R = _best_rotation(self._rest_centred, current - current.mean(axis=0))
            A0 = self._A0
            A1 = A0 @ R.T
        out = np.empty((len(self.rest), 3, 3))
        _frame_rotations(self.T0, T1, np.ascontiguousarray(A0), np.ascontiguousarray(A1), out)
        return out


@numba.njit(cache=True)
def _minimal_rotation_one(a, b, out):  # pragma: no cover - compiled
    # rotation taking unit a to unit b about a x b (Rodrigues); pi about a normal of a
    vx, vy, vz = a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]
    c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    s = np.sqrt(vx * vx + vy * vy + vz * vz)
    for i in range(3):
        for j in range(3):
            out[i, j] = 1.0 if i == j else 0.0
    if s > 1e-12:
        kx, ky, kz = vx / s, vy / s, vz / s
    elif c < 0:
        ex, ey, ez = (1.0, 0.0, 0.0) if abs(a[0]) < 0.9 else (0.0, 1.0, 0.0)
        kx, ky, kz = a[1] * ez - a[2] * ey, a[2] * ex - a[0] * ez, a[0] * ey - a[1] * ex
        n = np.sqrt(kx * kx + ky * ky + kz * kz)
        kx, ky, kz = kx / n, ky / n, kz / n
        s = 0.0
    else:
        return
    # R = I + s K + (1 - c) K^2 with K the cross-product matrix of k; K^2 = k k^T - I
    k = (kx, ky, kz)
    K = ((0.0, -kz, ky), (kz, 0.0, -kx), (-ky, kx, 0.0))
    for i in range(3):
        for j in range(3):
            kk = k[i] * k[j] - (1.0 if i == j else 0.0)
            out[i, j] += s * K[i][j] + (1.0 - c) * kk


@numba.njit(cache=True)
def _frame_rotations(T0, T1, A0, A1, out):  # pragma: no cover - compiled
    # per sample: frames (tangent, reference direction made normal, binormal) in both
    # poses and the rotation F1 F0^T; the minimal rotation where a frame is undefined
    # (scalar arithmetic only: array expressions compile slowly on a first run)
    for i in range(T0.shape[0]):
        d0 = A0[i, 0] * T0[i, 0] + A0[i, 1] * T0[i, 1] + A0[i, 2] * T0[i, 2]
        d1 = A1[i, 0] * T1[i, 0] + A1[i, 1] * T1[i, 1] + A1[i, 2] * T1[i, 2]
        n00, n01, n02 = A0[i, 0] - d0 * T0[i, 0], A0[i, 1] - d0 * T0[i, 1], A0[i, 2] - d0 * T0[i, 2]
        n10, n11, n12 = A1[i, 0] - d1 * T1[i, 0], A1[i, 1] - d1 * T1[i, 1], A1[i, 2] - d1 * T1[i, 2]
        l0 = np.sqrt(n00 * n00 + n01 * n01 + n02 * n02)
        l1 = np.sqrt(n10 * n10 + n11 * n11 + n12 * n12)
        scale = max(np.sqrt(A0[i, 0] ** 2 + A0[i, 1] ** 2 + A0[i, 2] ** 2), 1e-300)
        if l0 > 1e-6 * scale and l1 > 1e-6 * scale:
            n00, n01, n02 = n00 / l0, n01 / l0, n02 / l0
            n10, n11, n12 = n10 / l1, n11 / l1, n12 / l1
            t00, t01, t02 = T0[i, 0], T0[i, 1], T0[i, 2]
            t10, t11, t12 = T1[i, 0], T1[i, 1], T1[i, 2]
            n0 = (n00, n01, n02)
            n1 = (n10, n11, n12)
            t0 = (t00, t01, t02)
            t1 = (t10, t11, t12)
            b0 = (t01 * n02 - t02 * n01, t02 * n00 - t00 * n02, t00 * n01 - t01 * n00)
            b1 = (t11 * n12 - t12 * n11, t12 * n10 - t10 * n12, t10 * n11 - t11 * n10)
            for r in range(3):
                for c in range(3):
                    out[i, r, c] = t1[r] * t0[c] + n1[r] * n0[c] + b1[r] * b0[c]
        else:
            _minimal_rotation_one(T0[i], T1[i], out[i])


@numba.njit(cache=True)
def _quaternion_of(m, q):  # pragma: no cover - compiled
    # unit quaternion (w, x, y, z) of rotation matrix m, from its largest diagonal term
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    # the largest of (1 + tr, 1 + 2 m_00 - tr, 1 + 2 m_11 - tr, 1 + 2 m_22 - tr), first on ties
    j, best = 0, 1 + tr
    for c in range(3):
        if 1 + 2 * m[c, c] - tr > best:
            j, best = c + 1, 1 + 2 * m[c, c] - tr
    if j == 0:
        v = (1 + tr, m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1])
    elif j == 1:
        v = (m[2, 1] - m[1, 2], 1 + 2 * m[0, 0] - tr, m[0, 1] + m[1, 0], m[0, 2] + m[2, 0])
    elif j == 2:
        v = (m[0, 2] - m[2, 0], m[0, 1] + m[1, 0], 1 + 2 * m[1, 1] - tr, m[1, 2] + m[2, 1])
    else:
        v = (m[1, 0] - m[0, 1], m[0, 2] + m[2, 0], m[1, 2] + m[2, 1], 1 + 2 * m[2, 2] - tr)
    n = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3])
    q[0], q[1], q[2], q[3] = v[0] / n, v[1] / n, v[2] / n, v[3] / n


@numba.njit(cache=True)
def _matrix_of(q, M):  # pragma: no cover - compiled
    # rotation matrix of quaternion q (normalized here)
    n = np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    w, x, y, z = q[0] / n, q[1] / n, q[2] / n, q[3] / n
    M[0, 0], M[0, 1], M[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    M[1, 0], M[1, 1], M[1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    M[2, 0], M[2, 1], M[2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)


@numba.njit(cache=True)
def _quaternions_kernel(R, q):  # pragma: no cover - compiled
    for i in range(R.shape[0]):
        _quaternion_of(R[i], q[i])


@numba.njit(cache=True)
def _matrices_kernel(q, R):  # pragma: no cover - compiled
    for i in range(q.shape[0]):
        _matrix_of(q[i], R[i])


@numba.njit(cache=True)
def _blend_rotate(weights, R, first, delta, out):  # pragma: no cover - compiled
    # quaternions of the sample rotations, signs made to agree along each line,
    # Shepard-blended per cage vertex, turned back into a matrix; with deltas given,
    # out[v, :, 0] receives that matrix times the vertex's delta, else the matrix
    k = R.shape[0]
    q = np.empty((k, 4))
    _quaternions_kernel(R, q)
    # q and -q are the same rotation: make neighbouring samples agree in sign
    for i in range(1, k):
        p = 0 if first[i] else i - 1
        if q[i, 0] * q[p, 0] + q[i, 1] * q[p, 1] + q[i, 2] * q[p, 2] + q[i, 3] * q[p, 3] < 0:
            for c in range(4):
                q[i, c] = -q[i, c]
    qv = np.empty(4)
    M = np.empty((3, 3))
    for v in range(weights.shape[0]):
        for c in range(4):
            qv[c] = 0.0
        for i in range(k):
            for c in range(4):
                qv[c] += weights[v, i] * q[i, c]
        _matrix_of(qv, M)
        if delta.shape[0] == 0:
            for r in range(3):
                for c in range(3):
                    out[v, r, c] = M[r, c]
        else:
            for r in range(3):
                out[v, r, 0] = M[r, 0] * delta[v, 0] + M[r, 1] * delta[v, 1] + M[r, 2] * delta[v, 2]


def matrix_to_quaternion(R: FloatArray) -> FloatArray:
    """(k, 4) unit quaternions (w, x, y, z) of (k, 3, 3) rotation matrices."""
    q = np.empty((len(R), 4))
    _quaternions_kernel(np.ascontiguousarray(R, dtype=np.float64), q)
    return q


def quaternion_to_matrix(q: FloatArray) -> FloatArray:
    """(k, 3, 3) rotation matrices of (k, 4) quaternions (w, x, y, z), normalized first."""
    R = np.empty((len(q), 3, 3))
    _matrices_kernel(np.ascontiguousarray(q, dtype=np.float64), R)
    return R


class RotationField:
    """Blends per-sample rotations into one rotation per cage vertex.

    Each cage vertex takes a normalized quaternion average of the sample
    rotations with Shepard weights ``1 / (d**2 + h**2)**2`` of its rest
    distance ``d`` to each rest sample (``h`` the sample spacing), computed
    once per muscle. Equal sample rotations give exactly that rotation.

    Parameters
    ----------
    C : (m, 3) float64 array
        Rest cage vertices.
    samples : (k, 3) float64 array
        Rest skeleton samples.
    line : (k,) int array
        Line index of each sample.
    smoothing : float
        ``h`` above, in mesh units.
    """

    def __init__(
        self, C: FloatArray, samples: FloatArray, line: IntArray, smoothing: float
    ) -> None:
        d2 = np.sum((C[:, None, :] - samples[None, :, :]) ** 2, axis=2)
        w = 1.0 / (d2 + smoothing**2) ** 2
        self.weights = w / w.sum(axis=1, keepdims=True)
        self.line = np.asarray(line)
        self._first = np.concatenate([[True], self.line[1:] != self.line[:-1]])

    def rotations(self, R_samples: FloatArray) -> FloatArray:
        """(m, 3, 3) rotation per cage vertex from (k, 3, 3) sample rotations."""
        out = np.empty((self.weights.shape[0], 3, 3))
        _blend_rotate(
            self.weights, np.ascontiguousarray(R_samples), self._first, np.empty((0, 3)), out
        )
        return out

    def rotate(self, R_samples: FloatArray, delta: FloatArray) -> FloatArray:
        """(m, 3) vectors ``delta`` each turned by its cage vertex's blended rotation."""
        out = np.empty((self.weights.shape[0], 3, 1))
        _blend_rotate(
            self.weights,
            np.ascontiguousarray(R_samples),
            self._first,
            np.ascontiguousarray(delta, dtype=np.float64),
            out,
        )
        return out[:, :, 0]

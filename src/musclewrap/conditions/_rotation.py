"""Rotation of the Laplacian's differential coordinates by the skeleton's motion."""

from __future__ import annotations

import numba
import numpy as np

from .._typing import FloatArray, IntArray

__all__ = [
    "RotationField",
    "SampleRotations",
    "kabsch",
    "matrix_to_quaternion",
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
    Q0 = Q - Q.mean(axis=0)
    sv = np.linalg.svd(P0, compute_uv=False)
    determined = bool(len(P) >= 3 and sv[1] > 1e-6 * sv[0])
    U, _, Vt = np.linalg.svd(P0.T @ Q0)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, determined


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
        seg = np.empty((nseg, 3))
        for i in range(nseg):
            d = S[start + i + 1] - S[start + i]
            seg[i] = d / np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        for i in range(start, end + 1):
            j = i - start
            if j == 0:
                t = seg[0].copy()
            elif j == nseg:
                t = seg[nseg - 1].copy()
            else:
                t = seg[j - 1] + seg[j]
                if np.sqrt(t[0] ** 2 + t[1] ** 2 + t[2] ** 2) < 1e-9:
                    t = seg[j - 1].copy()
            T[i] = t / np.sqrt(t[0] ** 2 + t[1] ** 2 + t[2] ** 2)
        start = end + 1


def _minimal_rotation(a: FloatArray, b: FloatArray) -> FloatArray:
    """(k, 3, 3) rotations taking unit vectors ``a`` to ``b`` about ``a x b``."""
    v = np.cross(a, b)
    c = np.einsum("ij,ij->i", a, b)
    s = np.linalg.norm(v, axis=1)
    R = np.tile(np.eye(3), (len(a), 1, 1))
    ok = s > 1e-12
    k = np.zeros_like(v)
    k[ok] = v[ok] / s[ok, None]
    # opposite vectors: rotate by pi about any axis perpendicular to a
    anti = (~ok) & (c < 0)
    if anti.any():
        e = np.where(np.abs(a[anti, 0:1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        kk = np.cross(a[anti], e)
        k[anti] = kk / np.linalg.norm(kk, axis=1, keepdims=True)
        s = s.copy()
        s[anti] = 0.0
    K = np.zeros((len(a), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    sel = ok | anti
    R[sel] += s[sel, None, None] * K[sel] + (1 - c[sel, None, None]) * (K[sel] @ K[sel])
    return R


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
        sv = np.linalg.svd(self._rest_centred, compute_uv=False)
        self.collinear = not (len(rest) >= 3 and sv[1] > 1e-6 * sv[0])
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
            return _minimal_rotation(self.T0, T1)
        else:
            Q0 = current - current.mean(axis=0)
            U, _, Vt = np.linalg.svd(self._rest_centred.T @ Q0)
            d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
            R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
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
    K = np.array([[0.0, -kz, ky], [kz, 0.0, -kx], [-ky, kx, 0.0]])
    KK = K @ K
    for i in range(3):
        for j in range(3):
            out[i, j] += s * K[i, j] + (1.0 - c) * KK[i, j]


@numba.njit(cache=True)
def _frame_rotations(T0, T1, A0, A1, out):  # pragma: no cover - compiled
    # per sample: frames (tangent, reference direction made normal, binormal) in both
    # poses and the rotation F1 F0^T; the minimal rotation where a frame is undefined
    for i in range(T0.shape[0]):
        t0, t1, a0, a1 = T0[i], T1[i], A0[i], A1[i]
        n0 = a0 - (a0[0] * t0[0] + a0[1] * t0[1] + a0[2] * t0[2]) * t0
        n1 = a1 - (a1[0] * t1[0] + a1[1] * t1[1] + a1[2] * t1[2]) * t1
        l0 = np.sqrt(n0[0] ** 2 + n0[1] ** 2 + n0[2] ** 2)
        l1 = np.sqrt(n1[0] ** 2 + n1[1] ** 2 + n1[2] ** 2)
        scale = max(np.sqrt(a0[0] ** 2 + a0[1] ** 2 + a0[2] ** 2), 1e-300)
        if l0 > 1e-6 * scale and l1 > 1e-6 * scale:
            n0 = n0 / l0
            n1 = n1 / l1
            b0 = np.cross(t0, n0)
            b1 = np.cross(t1, n1)
            for r in range(3):
                for c in range(3):
                    out[i, r, c] = t1[r] * t0[c] + n1[r] * n0[c] + b1[r] * b0[c]
        else:
            _minimal_rotation_one(t0, t1, out[i])


@numba.njit(cache=True)
def _blend_rotate(weights, R, first, delta, out):  # pragma: no cover - compiled
    # quaternions of the sample rotations, signs made to agree along each line,
    # Shepard-blended per cage vertex, normalized, applied to that vertex's delta
    k = R.shape[0]
    q = np.empty((k, 4))
    for i in range(k):
        m = R[i]
        tr = m[0, 0] + m[1, 1] + m[2, 2]
        d = np.array([1 + tr, 1 + 2 * m[0, 0] - tr, 1 + 2 * m[1, 1] - tr, 1 + 2 * m[2, 2] - tr])
        j = np.argmax(d)
        if j == 0:
            v = (1 + tr, m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1])
        elif j == 1:
            v = (m[2, 1] - m[1, 2], 1 + 2 * m[0, 0] - tr, m[0, 1] + m[1, 0], m[0, 2] + m[2, 0])
        elif j == 2:
            v = (m[0, 2] - m[2, 0], m[0, 1] + m[1, 0], 1 + 2 * m[1, 1] - tr, m[1, 2] + m[2, 1])
        else:
            v = (m[1, 0] - m[0, 1], m[0, 2] + m[2, 0], m[1, 2] + m[2, 1], 1 + 2 * m[2, 2] - tr)
        n = np.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2 + v[3] ** 2)
        for c in range(4):
            q[i, c] = v[c] / n
    # q and -q are the same rotation: make neighbouring samples agree in sign
    for i in range(k):
        p = 0 if first[i] else i - 1
        if (
            i > 0
            and q[i, 0] * q[p, 0] + q[i, 1] * q[p, 1] + q[i, 2] * q[p, 2] + q[i, 3] * q[p, 3] < 0
        ):
            for c in range(4):
                q[i, c] = -q[i, c]
    for v in range(weights.shape[0]):
        w = x = y = z = 0.0
        for i in range(k):
            g = weights[v, i]
            w += g * q[i, 0]
            x += g * q[i, 1]
            y += g * q[i, 2]
            z += g * q[i, 3]
        n = np.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / n, x / n, y / n, z / n
        M = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        if delta.shape[0] == 0:
            out[v] = M
        else:
            for r in range(3):
                out[v, r, 0] = M[r, 0] * delta[v, 0] + M[r, 1] * delta[v, 1] + M[r, 2] * delta[v, 2]


def matrix_to_quaternion(R: FloatArray) -> FloatArray:
    """(k, 4) unit quaternions (w, x, y, z) of (k, 3, 3) rotation matrices."""
    m = R
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    cand = np.stack(
        [
            np.stack(
                [1 + tr, m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]],
                1,
            ),
            np.stack(
                [
                    m[:, 2, 1] - m[:, 1, 2],
                    1 + 2 * m[:, 0, 0] - tr,
                    m[:, 0, 1] + m[:, 1, 0],
                    m[:, 0, 2] + m[:, 2, 0],
                ],
                1,
            ),
            np.stack(
                [
                    m[:, 0, 2] - m[:, 2, 0],
                    m[:, 0, 1] + m[:, 1, 0],
                    1 + 2 * m[:, 1, 1] - tr,
                    m[:, 1, 2] + m[:, 2, 1],
                ],
                1,
            ),
            np.stack(
                [
                    m[:, 1, 0] - m[:, 0, 1],
                    m[:, 0, 2] + m[:, 2, 0],
                    m[:, 1, 2] + m[:, 2, 1],
                    1 + 2 * m[:, 2, 2] - tr,
                ],
                1,
            ),
        ],
        axis=1,
    )  # (k, 4 candidates, 4)
    diag = np.stack(
        [1 + tr, 1 + 2 * m[:, 0, 0] - tr, 1 + 2 * m[:, 1, 1] - tr, 1 + 2 * m[:, 2, 2] - tr], 1
    )
    best = np.argmax(diag, axis=1)
    q = cand[np.arange(len(R)), best]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def quaternion_to_matrix(q: FloatArray) -> FloatArray:
    """(k, 3, 3) rotation matrices of (k, 4) quaternions (w, x, y, z), normalized first."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], 1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], 1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], 1),
        ],
        axis=1,
    )


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

"""Rotation of the Laplacian's differential coordinates by the skeleton's motion."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = [
    "RotationField",
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
    T = np.zeros_like(S)
    for i in np.unique(line):
        idx = np.flatnonzero(line == i)
        P = S[idx]
        seg = np.diff(P, axis=0)
        seg /= np.linalg.norm(seg, axis=1, keepdims=True)
        t = np.empty_like(P)
        t[0], t[-1] = seg[0], seg[-1]
        t[1:-1] = seg[:-1] + seg[1:]
        n = np.linalg.norm(t, axis=1, keepdims=True)
        # a fold-back (opposite segments) leaves no direction: use the incoming one
        fold = n[:, 0] < 1e-9
        t[fold] = np.vstack([seg[0:1], seg])[fold]
        T[idx] = t / np.linalg.norm(t, axis=1, keepdims=True)
    return T


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
    T0 = _tangents(rest, line)
    T1 = _tangents(current, line)
    if reference_rest is not None and reference_current is not None:
        A0 = reference_rest[None, :] - rest
        A1 = reference_current[None, :] - current
    else:
        R, determined = kabsch(rest, current)
        if not determined:
            return _minimal_rotation(T0, T1)
        # a reference direction perpendicular to the skeleton's principal axis
        _, _, vt = np.linalg.svd(rest - rest.mean(axis=0))
        A0 = np.tile(vt[1], (len(rest), 1))
        A1 = A0 @ R.T
    N0 = A0 - np.einsum("ij,ij->i", A0, T0)[:, None] * T0
    N1 = A1 - np.einsum("ij,ij->i", A1, T1)[:, None] * T1
    n0 = np.linalg.norm(N0, axis=1)
    n1 = np.linalg.norm(N1, axis=1)
    scale = np.maximum(np.linalg.norm(A0, axis=1), 1e-300)
    ok = (n0 > 1e-6 * scale) & (n1 > 1e-6 * scale)
    out = _minimal_rotation(T0, T1)
    if ok.any():
        N0o, N1o = N0[ok] / n0[ok, None], N1[ok] / n1[ok, None]
        F0 = np.stack([T0[ok], N0o, np.cross(T0[ok], N0o)], axis=2)
        F1 = np.stack([T1[ok], N1o, np.cross(T1[ok], N1o)], axis=2)
        out[ok] = F1 @ np.transpose(F0, (0, 2, 1))
    return out


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
        q = matrix_to_quaternion(R_samples)
        # make neighbouring samples agree in sign (q and -q are the same rotation)
        ref = q[0].copy()
        for i in range(len(q)):
            prev = ref if self._first[i] else q[i - 1]
            if q[i] @ prev < 0:
                q[i] = -q[i]
        return quaternion_to_matrix(self.weights @ q)

"""Placing meshes segmented from another subject on a model: a similarity from landmarks."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._typing import FloatArray
from ..conditions import kabsch, minimal_rotation
from ..errors import SceneError
from ..mesh import face_areas, vertex_normals

__all__ = [
    "FEMUR_FITS",
    "axes_rotation",
    "cap_spread",
    "check_landmarks",
    "femur_landmarks",
    "fit_sphere",
    "landmark_point",
    "similarity",
    "surface_centroid",
]


def fit_sphere(P: FloatArray) -> tuple[FloatArray, float, float]:
    """Least-squares sphere through points (algebraic fit, then the true radius).

    Returns
    -------
    centre : (3,) array
    radius : float
    rms : float
        Root mean square distance of the points from the sphere.
    """
    P = np.asarray(P, dtype=np.float64)
    A = np.hstack([2 * P, np.ones((len(P), 1))])
    sol, *_ = np.linalg.lstsq(A, (P * P).sum(axis=1), rcond=None)
    c = sol[:3]
    d = np.linalg.norm(P - c, axis=1)
    r = float(d.mean())
    return c, r, float(np.sqrt(np.mean((d - r) ** 2)))


def surface_centroid(V: FloatArray, F: np.ndarray) -> FloatArray:
    """Area-weighted centroid of a triangle surface (independent of vertex density)."""
    area = face_areas(V, F)
    return (V[F].mean(axis=1) * area[:, None]).sum(axis=0) / area.sum()


def cap_spread(P: FloatArray, c: FloatArray) -> float:
    """How many ways the points ``P`` face from the centre ``c``: 0 for a band, 1/3 for a cap.

    The least second moment of their unit directions from ``c``: 1/3 on a whole sphere
    or a hemisphere, near 0 on a band round an axis (a shaft, a strap of muscle).
    """
    U = P - c
    U = U / np.maximum(np.linalg.norm(U, axis=1), 1e-300)[:, None]
    return float(np.linalg.eigvalsh(U.T @ U / len(U))[0])


#: the landmarks a whole femur's mesh gives (`femur_landmarks`), as a landmark's ``fit``
FEMUR_FITS = ("femoral_head", "femur_distal")


def femur_landmarks(
    V: FloatArray, F: np.ndarray, source: object
) -> tuple[FloatArray, FloatArray, str]:
    """The hip centre and the knee's point on a whole femur's mesh, and a few words on them.

    Along the mesh's longest principal axis (length ``L``), each end's fifth is searched
    for a sphere of radius 0.03-0.07 ``L`` (the femoral head's is 0.05: 0.052 on the LHDL
    femur, 0.053-0.055 on OpenSim's): each vertex votes for the centre one radius
    inward along its normal, in cells of 0.01 ``L``; the vertices within a quarter
    radius of the best centre's sphere are fitted, then those within a tenth of the
    fitted one, until it stays (the neck and trochanter left out: the centre within
    0.1 mm however the mesh lies, where the cells alone left it 1.6 mm apart). The head is the end whose best
    centre takes the larger share of its vertices (0.125 against 0.046 on the LHDL
    femur, 0.09-0.11 against 0.06 on OpenSim's coarse ones); the knee's point is the
    area-weighted centroid of the other end's tenth (the condyles: 1 cm above the knee
    joint's centre along the shaft on OpenSim's femurs, as a distal cartilage's centroid
    is). Raises `SceneError` (naming ``source``) where the ends' shares are within 25 %
    of each other, the head's sphere fits poorly (rms over a tenth of its radius), or
    its radius is not 0.035-0.075 of the length (part of a femur: its "knee" would be
    where the mesh was cut).
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    D = V - V.mean(axis=0)
    _, R = np.linalg.eigh(D.T @ D)
    t = D @ R[:, -1]
    L = float(t.max() - t.min())
    N = vertex_normals(V, F)
    ends = []
    for sel in (t > t.max() - 0.2 * L, t < t.min() + 0.2 * L):
        P, n = V[sel], N[sel]
        votes, best_r, best_c = 0, 0.0, np.zeros(3)
        for r in np.linspace(0.03, 0.07, 9) * L:
            cells, count = np.unique(
                np.floor((P - r * n) / (0.01 * L)).astype(np.int64), axis=0, return_counts=True
            )
            k = int(np.argmax(count))
            if count[k] > votes:
                votes, best_r, best_c = int(count[k]), r, (cells[k] + 0.5) * 0.01 * L
        on = np.abs(np.linalg.norm(P - best_c, axis=1) - best_r) < 0.25 * best_r
        ends.append((votes / max(len(P), 1), on, P))
    head = 0 if ends[0][0] >= ends[1][0] else 1
    share, other = ends[head][0], ends[1 - head][0]
    if not share >= 1.25 * other or ends[head][1].sum() < 4:
        raise SceneError(
            f"{source}: cannot tell the femoral head from the condyles (the ends' best spheres "
            f"take {share:.3f} and {other:.3f} of their vertices)"
        )
    P = ends[head][2]
    c, r, rms = fit_sphere(P[ends[head][1]])
    for _ in range(5):  # the head's own sphere: its vertices within a tenth of a radius, refitted
        on = np.abs(np.linalg.norm(P - c, axis=1) - r) < 0.1 * r
        if on.sum() < 4:
            break
        c_new, r, rms = fit_sphere(P[on])
        moved, c = float(np.linalg.norm(c_new - c)), c_new
        if moved < 1e-6 * L:
            break
    if not rms < 0.1 * r:
        raise SceneError(
            f"{source}: the femoral head is not sphere-like (radius {r:.3g}, rms {rms:.3g})"
        )
    # a head, not a tube: its vertices face every way (the least of the second moments of
    # their directions from the centre: 1/3 on a whole sphere or a hemisphere, 0.26-0.28 on
    # the three femurs at hand, 0.10-0.13 on the LHDL femur's halves, where the sphere
    # found is a band round the cut shaft)
    spread = cap_spread(P[on], c)
    if not spread >= 0.2:
        raise SceneError(
            f"{source}: no femoral head: the roundest end is a band, not a cap (spread "
            f"{spread:.2f}; part of a femur?)"
        )
    if not 0.035 <= r / L <= 0.075:
        raise SceneError(
            f"{source}: not a whole femur: its head's radius is {r / L:.3f} of its length "
            "(a whole femur's about 0.05)"
        )
    tc = t[F].mean(axis=1)
    distal = tc < t.min() + 0.1 * L if head == 0 else tc > t.max() - 0.1 * L
    knee = surface_centroid(V, F[distal])
    return c, knee, f"femoral head sphere r {r:.3g} (rms {rms:.2g}) of a femur {L:.4g} long"


def landmark_point(
    V: FloatArray, F: np.ndarray, fit: str, name: str, source: object
) -> tuple[FloatArray, str]:
    """A landmark's point on its mesh: a fitted sphere's centre, or the surface centroid.

    ``fit``: "sphere", "centroid", or one of `FEMUR_FITS` on a whole femur's mesh (its
    head's centre or its condyles' centroid, `femur_landmarks`). Returns the point and,
    for a sphere, a few words on the fit. Raises `SceneError` (naming ``source``) for a
    mesh that is not sphere-like (rms distance from the sphere over a quarter of its
    radius) or a femur whose head cannot be found.
    """
    if fit in FEMUR_FITS:
        head, knee, said = femur_landmarks(V, F, source)
        return (head, said) if fit == "femoral_head" else (knee, "")
    if fit != "sphere":
        return surface_centroid(V, F), ""
    c, r, rms = fit_sphere(V)
    if not rms < 0.25 * r:
        raise SceneError(
            f"{source}: landmark '{name}': the mesh is not sphere-like (fit radius "
            f"{r:.3g}, rms distance {rms:.3g}); use fit = 'centroid'"
        )
    return c, f"{name} sphere r {r:.1f} (rms {rms:.2f})"


def axes_rotation(axes: Sequence[str]) -> FloatArray:
    """Rotation whose rows pick the mesh axes that become the model's x, y and z.

    ``["y", "z", "x"]``: model x = mesh y, model y = mesh z, model z = mesh x;
    a leading ``-`` flips an axis. It must be a proper rotation (det +1).
    """
    unit = {"x": 0, "y": 1, "z": 2}
    R = np.zeros((3, 3))
    for i, a in enumerate(axes):
        sign = -1.0 if a.startswith("-") else 1.0
        R[i, unit[a.lstrip("+-")]] = sign
    return R


def similarity(P: FloatArray, Q: FloatArray, axes: FloatArray | None = None) -> FloatArray:
    """4x4 similarity (rotation, uniform scale, shift) taking landmarks ``P`` onto ``Q``.

    Parameters
    ----------
    P, Q : (n, 3) arrays
        Landmarks in the mesh's frame and in the model's, in the same order.
    axes : (3, 3) array, optional
        Rotation from `axes_rotation`; needed with two landmarks (it fixes the
        turn about the line through them), a start for nothing with three or more.

    Returns
    -------
    (4, 4) array

    Notes
    -----
    Two landmarks: the axes' rotation, then the smallest rotation taking the
    first-to-second direction onto the model's, the scale of their distances,
    and the shift that puts the first on the model's first. Three or more: the
    least-squares similarity of Umeyama (1991).
    """
    P = np.asarray(P, dtype=np.float64)
    Q = np.asarray(Q, dtype=np.float64)
    if len(P) == 2:
        R0 = np.eye(3) if axes is None else axes
        a, b = R0 @ (P[1] - P[0]), Q[1] - Q[0]
        s = float(np.linalg.norm(b) / np.linalg.norm(a))
        unit = np.array([a / np.linalg.norm(a), b / np.linalg.norm(b)])
        R = minimal_rotation(unit[:1], unit[1:])[0] @ R0
        t = Q[0] - s * R @ P[0]
    else:
        mp, mq = P.mean(axis=0), Q.mean(axis=0)
        X, Y = P - mp, Q - mq
        R = kabsch(X, Y)[0]  # Umeyama's rotation is Kabsch's; the scale follows from it
        s = float(np.sum((X @ R.T) * Y) / np.sum(X * X))
        t = mq - s * R @ mp
    T = np.eye(4)
    T[:3, :3] = s * R
    T[:3, 3] = t
    return T


def check_landmarks(P: FloatArray, names: Sequence[str], src: str) -> None:
    """Refuse coincident landmarks (no direction, no scale)."""
    P = np.asarray(P)
    for i in range(len(P)):
        for j in range(i + 1, len(P)):
            if np.linalg.norm(P[i] - P[j]) < 1e-9 * (1 + np.abs(P).max()):
                raise SceneError(f"{src}: landmarks '{names[i]}' and '{names[j]}' coincide")

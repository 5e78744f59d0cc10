"""Placing meshes segmented from another subject on a model: a similarity from landmarks."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._typing import FloatArray
from ..conditions import kabsch, minimal_rotation
from ..errors import SceneError
from ..mesh import face_areas

__all__ = [
    "axes_rotation",
    "check_landmarks",
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


def landmark_point(
    V: FloatArray, F: np.ndarray, fit: str, name: str, source: object
) -> tuple[FloatArray, str]:
    """A landmark's point on its mesh: a fitted sphere's centre, or the surface centroid.

    Returns the point and, for a sphere, a few words on the fit. Raises `SceneError`
    (naming ``source``) for a mesh that is not sphere-like (rms distance from the
    sphere over a quarter of its radius).
    """
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

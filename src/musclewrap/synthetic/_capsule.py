"""The capsule benchmark of the original 2012 implementation, and its scenarios."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = [
    "CAPSULE_SCENARIOS",
    "capsule",
    "capsule_scenario",
    "principal_axis_scenario",
    "rings_mesh",
    "sleeve",
]

CAPSULE_SCENARIOS = ("bend", "bend_short", "bend_long", "short", "rot")


def rings_mesh(
    z: FloatArray, r: FloatArray, n_around: int, x: FloatArray | None = None
) -> tuple[FloatArray, IntArray]:
    """Closed surface of revolution from rings between two poles.

    Parameters
    ----------
    z : (k,) float64 array
        Axial positions: first and last are the poles, the rest ring centres.
    r : (k,) float64 array
        Radii (first and last ignored).
    n_around : int
        Vertices per ring.
    x : (k,) float64 array, optional
        Lateral offset of each ring centre along x (to bend the axis).

    Returns
    -------
    V : (2 + (k - 2) * n_around, 3) float64 array
    F : (2 * n_around * (k - 2), 3) int64 array, outward oriented
    """
    x = np.zeros_like(z) if x is None else x
    nr = len(z) - 2
    ang = 2 * np.pi * np.arange(n_around) / n_around
    ring = np.stack(
        [
            (x[1:-1, None] + r[1:-1, None] * np.cos(ang)[None]).ravel(),
            (r[1:-1, None] * np.sin(ang)[None]).ravel(),
            np.repeat(z[1:-1], n_around),
        ],
        axis=1,
    )
    V = np.vstack([[x[0], 0.0, z[0]], ring, [x[-1], 0.0, z[-1]]])
    F = []
    j = np.arange(n_around)
    jn = (j + 1) % n_around
    F.append(np.stack([np.zeros(n_around, int), 1 + jn, 1 + j], 1))  # bottom fan
    for i in range(nr - 1):
        a = 1 + i * n_around
        bb = a + n_around
        F.append(np.stack([a + j, a + jn, bb + jn], 1))
        F.append(np.stack([a + j, bb + jn, bb + j], 1))
    top = len(V) - 1
    last = 1 + (nr - 1) * n_around
    F.append(np.stack([np.full(n_around, top), last + j, last + jn], 1))
    return V, np.vstack(F).astype(np.int64)


def capsule(
    radius: float = 20.0,
    length: float = 160.0,
    n_around: int = 96,
    cap_rings: int = 24,
    segments: int = 110,
) -> tuple[FloatArray, IntArray]:
    """Capsule along +z from the pole at the origin (the 2012 benchmark mesh).

    Defaults give 15,074 vertices and 30,144 triangles: radius 20, cylinder
    length 160 (total 200), 96 vertices per ring, 24 rings per cap (pole
    included), 110 cylinder segments.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    """
    phi = np.pi / 2 * np.arange(1, cap_rings) / cap_rings
    zb = radius - radius * np.cos(phi)
    rb = radius * np.sin(phi)
    zc = radius + length * np.arange(segments + 1) / segments
    z = np.concatenate([[0.0], zb, zc, (2 * radius + length - zb)[::-1], [2 * radius + length]])
    r = np.concatenate([[0.0], rb, np.full(segments + 1, radius), rb[::-1], [0.0]])
    return rings_mesh(z, r, n_around)


def sleeve(
    inner: float,
    outer: float,
    length: float,
    n_around: int = 64,
    segments: int = 30,
    cap_rings: int = 3,
) -> tuple[FloatArray, IntArray]:
    """A thick-walled tube along +z from 0 to ``length``, closed by flat annular ends (genus 1).

    A muscle wrapped round a bone or round another muscle (the vasti round the vastus
    intermedius round the femur). Its walls at radii ``inner`` and ``outer`` have
    ``segments`` bands, each end ``cap_rings`` bands.

    Returns
    -------
    V : (n_around * 2 * (segments + cap_rings), 3) float64 array
    F : (2 * n_around * 2 * (segments + cap_rings), 3) int64 array, outward oriented
    """
    if not 0.0 < inner < outer or length <= 0.0:
        raise ValueError(
            f"a sleeve needs 0 < inner < outer and length > 0: {inner}, {outer}, {length}"
        )
    up = length * np.arange(segments) / segments
    across = inner + (outer - inner) * np.arange(cap_rings) / cap_rings
    # the profile, a closed loop in (r, z): up the outer wall, in across the top, down the
    # inner wall, out across the bottom
    r = np.concatenate(
        [np.full(segments, outer), outer + inner - across, np.full(segments, inner), across]
    )
    z = np.concatenate([up, np.full(cap_rings, length), length - up, np.zeros(cap_rings)])
    ang = 2 * np.pi * np.arange(n_around) / n_around
    V = np.stack(
        [
            (r[:, None] * np.cos(ang)).ravel(),
            (r[:, None] * np.sin(ang)).ravel(),
            np.repeat(z, n_around),
        ],
        axis=1,
    )
    k = len(r)
    i = np.arange(k)[:, None] * n_around
    n = (np.arange(k)[:, None] + 1) % k * n_around
    j, jn = np.arange(n_around), (np.arange(n_around) + 1) % n_around
    # the profile runs counter-clockwise in (r, z) seen with the angle growing away from
    # the viewer: these windings point out of the solid
    F = np.concatenate(
        [np.stack([i + j, n + jn, n + j], axis=2), np.stack([i + j, i + jn, n + jn], axis=2)]
    ).reshape(-1, 3)
    return V, F.astype(np.int64)


def capsule_scenario(
    name: str, total: float = 200.0
) -> tuple[dict[str, FloatArray], dict[str, FloatArray]]:
    """Rest and current action lines of a capsule scenario.

    Parameters
    ----------
    name : {"bend", "bend_short", "bend_long", "short", "rot"}
        ``bend``: 3 points, the second half bent 30 degrees at mid-length,
        same length; ``bend_short`` / ``bend_long``: the same 15 % shorter /
        10 % longer; ``short``: straight, 15 % shorter; ``rot``: 2 points,
        rigid 20 degree rotation about x through the first pole.
    total : float, optional
        Pole-to-pole length.

    Returns
    -------
    rest, current : dict of str to array
        One line named ``"axis"``.
    """
    rest = {"axis": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, total]])}
    scale = {"bend": 1.0, "bend_short": 0.85, "bend_long": 1.10}
    if name in scale:
        h = total / 2 * scale[name]
        a = np.radians(30.0)
        cur = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, h], [h * np.sin(a), 0.0, h + h * np.cos(a)]])
    elif name == "short":
        cur = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.85 * total]])
    elif name == "rot":
        a = np.radians(20.0)
        R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        cur = rest["axis"] @ R.T
    else:
        raise ValueError(f"unknown capsule scenario {name!r}; choose from {CAPSULE_SCENARIOS}")
    return rest, {"axis": cur}


def principal_axis_scenario(
    V: FloatArray, name: str
) -> tuple[dict[str, FloatArray], dict[str, FloatArray]]:
    """A capsule scenario applied to any muscle along its own principal axis.

    The rest line joins the extreme projections of the vertices on the first
    principal axis; ``bend``, ``bend_short`` and ``bend_long`` bend its second
    half by 30 degrees towards the second principal axis (same length, 15%
    shorter, 10% longer), ``short`` shortens it by 15%, ``rot`` turns it
    rigidly by 20 degrees about the third axis through its first end.

    Parameters
    ----------
    V : (n, 3) float64 array
        Rest vertices of the muscle.
    name : str
        One of `CAPSULE_SCENARIOS`.

    Returns
    -------
    rest, current : dict of str to array
        One line named ``"axis"`` in each pose.
    """
    if name not in CAPSULE_SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; choose one of {CAPSULE_SCENARIOS}")
    c = V.mean(axis=0)
    _, _, vt = np.linalg.svd(V - c, full_matrices=False)
    ax = vt[0]
    proj = (V - c) @ ax
    p0, p1 = c + proj.min() * ax, c + proj.max() * ax
    length = proj.max() - proj.min()
    rest = {"axis": np.array([p0, p1])}
    scale = {"bend": 1.0, "bend_short": 0.85, "bend_long": 1.10}
    if name in scale:
        h = length / 2 * scale[name]
        a = np.radians(30.0)
        mid = p0 + h * ax
        cur = np.array([p0, mid, mid + h * (np.cos(a) * ax + np.sin(a) * vt[1])])
    elif name == "short":
        cur = np.array([p0, p0 + 0.85 * length * ax])
    else:  # rot
        k = vt[2]
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        a = np.radians(20.0)
        R = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * (K @ K)
        cur = (rest["axis"] - p0) @ R.T + p0
    return rest, {"axis": cur}

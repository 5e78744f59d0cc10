"""The posture a subject's meshes were taken in, fitted to the model's bones.

Meshes of another subject placed on a model by landmarks on one body (`similarity`: the
hip's centre and the knee's on the femur) sit right on that body, but the bodies beyond
its joints (the pelvis, beyond the hip) lie as the model's rest pose puts them, not as
the subject lay in the scanner: the Visible Human Female's hip, registered at gait2392's
zero angles, puts her psoas 14.8 mm into the model's sacrum and her gluteus medius 6.2 mm
into its pelvis (BENCHMARKS.md, "The posture the meshes were taken in"). `fit_posture`
searches the rest pose's coordinates of those joints for the one where the registered
meshes lie clearest of the model's bones they do not move with: every candidate on a
grid, then a finer grid round the best (no local descent to stall on a wrong side).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from ..mesh import vertex_areas

__all__ = ["PostureFit", "fit_posture"]


@dataclass(frozen=True)
class PostureFit:
    """What `fit_posture` found.

    ``change`` (k,) what each coordinate's rest value gains (model units: radians for a
    rotation); ``price`` the registered meshes' squared shortfall under the margin,
    summed over their surface (mesh units^4), at the rest pose given and at the fitted
    one; ``before`` and ``after`` per mesh the vertices inside any of the bones and
    the deepest of them (only meshes that have any, before or after); ``settled``
    False where the least price lies on the edge of what was searched (the price may
    fall on past it: the bones do not settle the posture within it); ``bones`` the
    bones' names where the caller gave them.
    """

    coordinates: tuple[str, ...]
    change: FloatArray
    price: tuple[float, float]
    before: dict[str, tuple[int, float]]
    after: dict[str, tuple[int, float]]
    settled: bool = True
    bones: tuple[str, ...] = ()


def fit_posture(
    meshes: Mapping[str, tuple[FloatArray, IntArray]],
    bones: Sequence[tuple[FloatArray, IntArray]],
    place: Callable[[FloatArray], Sequence[FloatArray]],
    coordinates: Sequence[str],
    *,
    reach: float = np.radians(10.0),
    step: float = np.radians(2.5),
    fine: float = np.radians(0.5),
    margin: float = 2.0,
    spacing: float = 2.0,
    alike: float = 0.02,
    cap: float = 4.0,
) -> PostureFit:
    """The change of the rest pose's ``coordinates`` that takes ``meshes`` clearest of ``bones``.

    The price of a change ``dq`` is the sum over the meshes' vertices of their area (a
    third of their triangles') times the squared shortfall of their signed distance to
    the nearest bone under ``margin`` (inside a bone: more than the margin short), each
    shortfall at most ``cap``: a vertex deep in a bone at every posture (a generic bone
    of another shape) weighs no more than one just in it. ``place(dq)`` gives, per bone,
    the transform from the meshes' frame into the bone's at the rest pose plus ``dq``.
    Every ``dq`` within ``reach`` of zero on a grid of ``step`` is priced (on every
    fourth vertex that may come near a bone), then every one within ``step`` of the
    best on a grid of twice ``fine`` (every second), then within ``fine`` of that on a
    grid of ``fine`` (all); the least price wins. Then each coordinate goes back towards
    zero, a ``fine`` at a time, while the price stays within ``alike`` of the least: a
    coordinate the bones do not tell (the price flat along it) keeps the rest pose's
    value, and a rest pose already fitted stays. The bones' signed distances are
    sampled once on a grid of ``spacing`` and read trilinearly.

    Parameters
    ----------
    meshes : mapping of str to (V, F)
        The registered meshes (closed), in one frame (the registration's).
    bones : sequence of (V, F)
        The model's bones they do not move with, each in its body's frame (closed).
    place : callable
        ``dq`` (k,) -> one 4 x 4 transform per bone, meshes' frame to the bone's.
    coordinates : sequence of str
        The k coordinates ``dq`` changes (named in the result).
    reach, step, fine : float
        The search (model units: radians for a rotation).
    margin, spacing, cap : float
        Mesh units.
    alike : float
        A fraction of the least price. The VHF leg with gait2392's pelvis and sacrum
        (BENCHMARKS.md, "The posture the meshes were taken in") gives each either side.

    Returns
    -------
    PostureFit
    """
    import igl
    from scipy.ndimage import map_coordinates

    k = len(coordinates)
    names = list(meshes)
    P = np.vstack([np.asarray(meshes[n][0], dtype=np.float64) for n in names])
    # a third of each vertex's triangles' area
    w = np.concatenate([vertex_areas(*meshes[n]) / 3.0 for n in names])
    owner = np.repeat(np.arange(len(names)), [len(meshes[n][0]) for n in names])
    Ph = np.hstack([P, np.ones((len(P), 1))])
    n = int(round(reach / step))
    coarse = np.array(list(itertools.product(np.arange(-n, n + 1) * step, repeat=k)))
    zero = np.zeros(k)
    rest = [np.asarray(T, dtype=np.float64) for T in place(zero)]
    # how far any candidate can move each vertex, per bone: the most over the search's
    # corners (just past them); a move is all but linear in dq for turns this small, and
    # the largest of a convex function over a box is at a corner; 1.25 times that
    corners = np.array(list(itertools.product((-1.0, 1.0), repeat=k))) * (reach + step)
    moves = [[T @ np.linalg.inv(T0) for T, T0 in zip(place(dq), rest, strict=True)]
             for dq in corners]  # fmt: skip
    fields = []
    for b, ((V, F), T0) in enumerate(zip(bones, rest, strict=True)):
        V = np.ascontiguousarray(V, dtype=np.float64)
        F = np.ascontiguousarray(F, dtype=np.int64)
        pad = margin + 2.0 * spacing
        lo = V.min(axis=0) - pad
        shape = np.ceil((V.max(axis=0) + pad - lo) / spacing).astype(int) + 1
        axes = [lo[d] + spacing * np.arange(shape[d]) for d in range(3)]
        G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        sd = igl.signed_distance(
            G, V, F, sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER,
        )[0]  # fmt: skip
        hi = lo + spacing * (shape - 1)
        Y = Ph @ T0.T[:, :3]
        reach_y = np.zeros(len(Y))
        for M in moves:
            reach_y = np.maximum(
                reach_y, np.linalg.norm(Y @ M[b][:3, :3].T + M[b][:3, 3] - Y, axis=1)
            )
        reach_y *= 1.25
        # those that cannot come within the margin of the bone (the distance is 1-Lipschitz;
        # a spacing more for reading it off the grid), or into the grid, are left out
        out = np.linalg.norm(Y - np.clip(Y, lo, hi), axis=1)
        keep = out <= reach_y
        inner = np.flatnonzero(out == 0.0)
        d0 = map_coordinates(sd.reshape(shape), ((Y[inner] - lo) / spacing).T, order=1)
        keep[inner] = d0 <= margin + spacing + reach_y[inner]
        keep = np.flatnonzero(keep)
        fields.append((lo, shape, sd.reshape(shape), V, F, keep))

    def shortfall(dq: FloatArray, every: int = 1) -> FloatArray:
        """Each vertex's squared shortfall under the margin (at most ``cap``), nearest bone.

        ``every``: only every so many of the vertices that may come near are priced
        (the others 0).
        """
        short = np.zeros(len(Ph))
        for (lo, shape, sd, _, _, keep), T in zip(fields, place(dq), strict=True):
            keep = keep[::every]
            if not len(keep):
                continue
            idx = (Ph[keep] @ np.asarray(T, dtype=np.float64).T[:, :3] - lo) / spacing
            inside = np.all((idx >= 0) & (idx <= shape - 1), axis=1)
            if inside.any():
                d = map_coordinates(sd, idx[inside].T, order=1, mode="nearest")
                i = keep[inside]
                short[i] = np.maximum(short[i], np.clip(margin - d, 0.0, cap) ** 2)
        return short

    def price(dq: FloatArray, every: int = 1) -> float:
        return float(w @ shortfall(dq, every))

    def best_of(grid: FloatArray, every: int) -> FloatArray:
        grid = np.vstack([zero, grid])  # the rest pose given is always a candidate
        prices = np.array([price(dq, every) for dq in grid])
        tied = np.flatnonzero(prices == prices.min())
        return grid[tied[np.argmin((grid[tied] ** 2).sum(axis=1))]]

    # the coarse grid on a quarter of the vertices near the bones; then, round the best so
    # far, a grid of twice `fine` within a step on half of them, and `fine` on all
    change = best_of(coarse, 4)
    wide = int(step / (2.0 * fine) + 1e-9)  # the middle grid's half-width, in its spacing
    for grid, half, every in ((2.0 * fine, wide, 2), (fine, 1, 1)):
        offsets = np.arange(-half, half + 1) * grid
        change = best_of(change + np.array(list(itertools.product(offsets, repeat=k))), every)
    change = np.round(change / fine) * fine  # on the grid, less its sums' last bits
    # the best on the edge of what was searched (the coarse grid's reach and the finer
    # grids' way past it): the price may fall on beyond it
    edge = reach + 2.0 * fine * wide + fine
    settled = bool(np.all(np.abs(change) < edge - 0.5 * fine))
    # each coordinate back towards the rest pose given while the price stays within
    # `alike` of the least: one the bones do not tell (the price flat along it: the hip's
    # rotation on the VHF leg) keeps its value, and a pose already fitted stays
    least = price(change)
    for i in range(k):
        for v in np.arange(0, abs(change[i]) + 0.5 * fine, fine) * np.sign(change[i]):
            dq = change.copy()
            dq[i] = v
            if v == change[i] or price(dq) <= least * (1.0 + alike):
                change = dq
                break

    def overlaps(dq: FloatArray) -> dict[str, tuple[int, float]]:
        deepest = np.zeros(len(P))
        for (_, _, _, V, F, _), T in zip(fields, place(dq), strict=True):
            X = Ph @ np.asarray(T, dtype=np.float64).T[:, :3]
            s = igl.signed_distance(
                X, V, F, sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER,
            )[0]  # fmt: skip
            deepest = np.maximum(deepest, -s)
        out = {}
        for i, name in enumerate(names):
            d = deepest[owner == i]
            out[name] = (int((d > 0).sum()), float(max(0.0, d.max(initial=0.0))))
        return out

    before, after = overlaps(zero), overlaps(change)
    touched = [nm for nm in names if before[nm][0] or after[nm][0]]
    return PostureFit(
        coordinates=tuple(coordinates),
        change=change,
        price=(float(w @ shortfall(zero)), float(w @ shortfall(change))),
        before={nm: before[nm] for nm in touched},
        after={nm: after[nm] for nm in touched},
        settled=settled,
    )

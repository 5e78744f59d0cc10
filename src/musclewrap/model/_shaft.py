"""A model's long bone fitted to the subject's muscles: its shaft moved where they leave room.

A model's bone registered on another subject's muscles by its joints (`similarity`) sits
right at the hip and the knee, and wherever the two subjects' shafts bow differently in
between, in the muscles: gait2392's femur on the Visible Human Female lies 11.1 mm deep
in the vastus intermedius, its shaft as thick as the room the muscles leave but 11-14 mm
anterior of it (BENCHMARKS.md, "Fitting the model's bones to the subject's muscles").
`fit_shaft` moves each cross-section of the bone across its long axis, as a whole (the
bone keeps its sections' shape and size), by the smooth curve of offsets that clears
the muscles best: each level's offsets are searched on a grid, every one of them (no
local descent to stall on a wrong side), and the levels are chained by dynamic
programming, a smooth curve held at zero where the bone must stay.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = ["ShaftFit", "fit_shaft"]


@dataclass(frozen=True)
class ShaftFit:
    """What `fit_shaft` did to a bone.

    ``V`` the bone's vertices moved (same faces); ``levels`` (L,) the cross-sections'
    places along ``axis`` from ``centre``; ``offsets`` (L, 2) each one's move along
    ``across`` (2, 3); ``held`` (L,) the levels kept where they were; ``ends`` (2,) the
    places past the bone's ends where the move is back to zero; ``moved`` the
    largest move of a vertex; ``before`` and ``after`` per muscle the muscle's vertices
    in the bone and the deepest of them (only muscles that have any, before or after).
    """

    V: FloatArray
    centre: FloatArray
    axis: FloatArray
    across: FloatArray
    levels: FloatArray
    offsets: FloatArray
    held: np.ndarray
    ends: FloatArray
    moved: float
    before: dict[str, tuple[int, float]]
    after: dict[str, tuple[int, float]]

    def move(self, P: FloatArray) -> FloatArray:
        """The move (n, 3) of points ``P`` (n, 3) of the bone (its closed copy's too).

        The offsets' monotone cubic (PCHIP) along the axis, zero past the ends.
        """
        from scipy.interpolate import PchipInterpolator  # a fifth of a second to import

        xs = np.r_[self.ends[0], self.levels, self.ends[1]]
        ys = np.vstack([[0.0, 0.0], self.offsets, [0.0, 0.0]])
        curve = PchipInterpolator(xs, ys)
        a = (np.asarray(P, dtype=np.float64) - self.centre) @ self.axis
        return curve(np.clip(a, xs[0], xs[-1])) @ self.across


def fit_shaft(
    V: FloatArray,
    F: IntArray,
    muscles: Mapping[str, tuple[FloatArray, IntArray]],
    held: FloatArray,
    *,
    step: float = 10.0,
    reach: float = 20.0,
    grid: float = 1.0,
    margin: float = 2.0,
    smooth: float = 500.0,
    stay: float = 0.5,
) -> ShaftFit:
    """Move a long bone's cross-sections across its axis, out of the muscles round it.

    The bone ``(V, F)`` (closed) is cut across its longest principal axis every ``step``
    (mesh units). At each level every move ``t`` of the section within ``reach``, on a
    ``grid``, is priced by how far its cells (inside the section, and on its outline)
    would lie closer than ``margin`` to a muscle or in it: the sum of the squared
    shortfalls times the cells' area, per unit of length. Over the levels the offsets
    ``t_k`` minimise that price plus ``stay |t_k|^2`` (the least move among equally clear
    ones) plus ``smooth |t_k - t_k-1|^2 / step^2`` (a bent shaft costs), summed times
    ``step``; found exactly over the grid by dynamic programming, so no wrong side can
    stall it. Levels within ``step / 2`` of a point of ``held`` (the body's own bones of
    the subject, its joints' centres), and those past the outermost held points along
    the axis, stay where they are. A monotone cubic (PCHIP: no overshoot, so a held
    stretch stays exactly where it was) through the offsets, zero past the bone's ends,
    moves each vertex.

    Parameters
    ----------
    V, F : arrays
        The bone, closed, in the same frame as the muscles.
    muscles : mapping of str to (V, F)
        The closed muscle surfaces it may touch.
    held : (k, 3) array
        Points where the bone is known to be right.
    step, reach, grid, margin, smooth, stay : float
        As above; mesh units (``smooth`` and ``stay`` weigh squared mesh units against
        the price's squared shortfalls over a unit area). Measured on the VHF leg with
        gait2392's femur (the vastus intermedius's vertices left in it, and how deep;
        BENCHMARKS.md): the defaults 31, 0.37 mm (moved 14.9 mm); ``margin`` 0: 940,
        2.16 mm, 1: 248, 1.18 mm, 3: none (moved 15.7 mm); ``step`` 5: 7, 0.26 mm
        (1.5x the time); ``stay`` 0.05: none (15.7 mm), 5: 880, 2.15 mm (12.6 mm);
        ``smooth`` 100 or 2,500 and ``reach`` 30: within 4 vertices of the defaults.
        What is left, the run's push-out at rest takes (volume kept).

    Returns
    -------
    ShaftFit
    """
    import igl
    import trimesh

    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    held = np.asarray(held, dtype=np.float64).reshape(-1, 3)
    centre = V.mean(axis=0)
    _, R = np.linalg.eigh((V - centre).T @ (V - centre))
    axis, across = R[:, 2], R[:, :2].T.copy()
    a = (V - centre) @ axis
    lo, hi = float(a.min()), float(a.max())
    levels = np.arange(lo + step / 2, hi, step)
    keep = np.zeros(len(levels), dtype=bool)
    if len(held):
        ha = (held - centre) @ axis
        keep |= (levels < ha.min()) | (levels > ha.max())
        keep |= (np.abs(levels[:, None] - ha[None, :]) <= step / 2).any(axis=1)
    n = int(round(reach / grid))
    shifts = np.arange(-n, n + 1) * grid
    T = np.stack(np.meshgrid(shifts, shifts, indexing="ij"), axis=-1).reshape(-1, 2)
    zero = len(T) // 2
    mesh = trimesh.Trimesh(V, F, process=False)
    price = np.zeros((len(levels), len(T)))
    sections = {
        k: _section(mesh, V, F, centre + levels[k] * axis, across, n, grid)
        for k in range(len(levels))
        if not keep[k]
    }
    sections = {k: s for k, s in sections.items() if s is not None}
    if sections:
        # scipy.signal (with scipy.stats) is half a second to import in every process
        from scipy.signal import correlate

        # every level's points at once: libigl builds its tree over a muscle per call
        P = np.vstack([s[1] for s in sections.values()])
        clear = _clearance(P, muscles, margin)
        start = 0
        for k, (cells, Pk, shape) in sections.items():
            short = np.maximum(0.0, margin - clear[start : start + len(Pk)]) ** 2
            start += len(Pk)
            # price(t) = sum over the section's cells c of short[c + t]: a correlation,
            # summed directly (not by FFT: the same bits on any machine, ties included)
            c = correlate(short.reshape(shape), cells.astype(np.float64), "valid", "direct")
            price[k] = c.ravel() * grid * grid
    price = step * (price + stay * (T * T).sum(axis=1))
    path = _chain(price, keep, zero, (smooth / step) * ((T[:, None] - T[None]) ** 2).sum(axis=-1))
    offsets = T[path]
    ends = np.array([lo - step, hi + step])
    fit = ShaftFit(V, centre, axis, across, levels, offsets, keep, ends, 0.0, {}, {})
    move = fit.move(V)
    V2 = V + move

    def overlaps(P: FloatArray) -> dict[str, tuple[int, float]]:
        out = {}
        for name, (Vm, Fm) in muscles.items():
            s = igl.signed_distance(
                np.ascontiguousarray(Vm, dtype=np.float64),
                P,
                F,
                sign_type=igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL,
                upper_bound=1.0,
            )[0]
            out[name] = (int((s < 0).sum()), float(max(0.0, -s.min())))
        return out

    before, after = overlaps(V), overlaps(V2)
    touched = [m for m in muscles if before[m][0] or after[m][0]]
    return dataclasses.replace(
        fit,
        V=V2,
        moved=float(np.linalg.norm(move, axis=1).max(initial=0.0)),
        before={m: before[m] for m in touched},
        after={m: after[m] for m in touched},
    )


def _section(
    mesh: object,
    V: FloatArray,
    F: IntArray,
    origin: FloatArray,
    across: FloatArray,
    n: int,
    grid: float,
) -> tuple[np.ndarray, FloatArray, tuple[int, int]] | None:
    """The bone's cells across ``origin`` (inside it, or on its outline), and more points.

    The points: the cells' box grown by ``n`` cells each way, where the muscles'
    clearance is needed.
    """
    import trimesh

    normal = np.cross(across[0], across[1])
    seg = trimesh.intersections.mesh_plane(mesh, normal, origin)
    if len(seg) == 0:
        return None
    seg2 = (seg - origin) @ across.T
    uv = seg2.reshape(-1, 2)
    first = np.floor(uv.min(axis=0) / grid).astype(np.int64) - 1
    last = np.ceil(uv.max(axis=0) / grid).astype(np.int64) + 1
    UU, VV = np.meshgrid(
        np.arange(first[0], last[0] + 1) * grid,
        np.arange(first[1], last[1] + 1) * grid,
        indexing="ij",
    )
    cells = _inside_outline(np.c_[UU.ravel(), VV.ravel()], seg2).reshape(UU.shape)
    for t in np.linspace(0.0, 1.0, 5):
        on = np.round((seg2[:, 0] * (1 - t) + seg2[:, 1] * t) / grid).astype(np.int64) - first
        cells[on[:, 0], on[:, 1]] = True
    UU, VV = np.meshgrid(
        np.arange(first[0] - n, last[0] + n + 1) * grid,
        np.arange(first[1] - n, last[1] + n + 1) * grid,
        indexing="ij",
    )
    P = origin + UU.reshape(-1, 1) * across[0] + VV.reshape(-1, 1) * across[1]
    return cells, P, UU.shape


def _inside_outline(Q: FloatArray, seg: FloatArray) -> np.ndarray:
    """Which points ``Q`` (n, 2) the closed outline ``seg`` (m, 2, 2) encloses (even-odd)."""
    a, b = seg[:, 0], seg[:, 1]
    inside = np.zeros(len(Q), dtype=bool)
    for start in range(0, len(Q), 4096):
        q = Q[start : start + 4096, None, :]
        # the segments a ray from the point along +u crosses
        spans = (a[None, :, 1] > q[..., 1]) != (b[None, :, 1] > q[..., 1])
        dy = np.where(spans, b[None, :, 1] - a[None, :, 1], 1.0)
        u = a[None, :, 0] + (q[..., 1] - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / dy
        inside[start : start + 4096] = (spans & (u > q[..., 0])).sum(axis=1) % 2 == 1
    return inside


def _clearance(
    P: FloatArray, muscles: Mapping[str, tuple[FloatArray, IntArray]], margin: float
) -> FloatArray:
    """Each point's signed distance to the nearest muscle (negative inside one).

    Only where under ``margin``: points farther than that from a muscle's box are not
    measured (inf), and distances past it are bounded.
    """
    import igl

    clear = np.full(len(P), np.inf)
    for Vm, Fm in muscles.values():
        lo, hi = Vm.min(axis=0) - margin, Vm.max(axis=0) + margin
        near = np.flatnonzero(((P >= lo) & (P <= hi)).all(axis=1))
        if len(near):
            # pseudo-normal signs: exact for a closed surface; nothing past the margin needed
            s = igl.signed_distance(
                P[near],
                np.ascontiguousarray(Vm, dtype=np.float64),
                np.ascontiguousarray(Fm, dtype=np.int64),
                sign_type=igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL,
                upper_bound=2.0 * margin + 1.0,
            )[0]
            clear[near] = np.minimum(clear[near], s)
    return clear


def _chain(price: FloatArray, keep: np.ndarray, zero: int, jump: FloatArray) -> IntArray:
    """The states (one per level) of least price plus jumps; ``keep`` levels at ``zero``."""
    L, S = price.shape
    total = price[0].copy()
    if keep[0]:
        total = np.where(np.arange(S) == zero, total, np.inf)
    back = np.empty((max(L - 1, 0), S), dtype=np.int64)
    for k in range(1, L):
        both = total[None, :] + jump  # [to, from]
        back[k - 1] = np.argmin(both, axis=1)
        total = both[np.arange(S), back[k - 1]] + price[k]
        if keep[k]:
            total = np.where(np.arange(S) == zero, total, np.inf)
    s = int(np.argmin(total))
    path = [s]
    for k in range(L - 2, -1, -1):
        s = int(back[k, s])
        path.append(s)
    return np.asarray(path[::-1], dtype=np.int64)

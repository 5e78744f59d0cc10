"""How well action lines fit a muscle mesh at rest: the figures `init` and `check` judge by."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._cache import cached_measure
from .._typing import FloatArray, IntArray

__all__ = ["LineFit", "line_fit", "line_fits", "outside_distance", "resample_polyline"]


def resample_polyline(P: FloatArray, step: float) -> FloatArray:
    """Points along a poly-line at most ``step`` apart (its own points included)."""
    P = np.asarray(P, dtype=np.float64)
    out = [P[:1]]
    for a, b in zip(P[:-1], P[1:], strict=True):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        t = np.arange(1, n + 1)[:, None] / n
        out.append(a + t * (b - a))
    return np.vstack(out)


def outside_distance(
    P: FloatArray, V: FloatArray, F: IntArray, *, cache: Path | None = None
) -> FloatArray:
    """Each point's distance outside the closed surface ``V, F`` (0 inside it).

    ``cache``: a folder where the same arrays' distances, measured before, are read back
    (`musclewrap._cache.cached_measure`): libigl builds its trees over ``V, F`` at every
    call, and ``musclewrap run`` and ``view`` check their scene at every start.
    """
    import igl

    P = np.ascontiguousarray(P, dtype=np.float64)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)

    def measure() -> dict[str, np.ndarray]:
        d2, _, _ = igl.point_mesh_squared_distance(P, V, F)
        inside = igl.fast_winding_number(V, F, P) > 0.5
        return {"d": np.where(inside, 0.0, np.sqrt(d2))}

    return cached_measure(cache, "outside-1", [P, V, F], measure)["d"]


@dataclass(frozen=True)
class LineFit:
    """A muscle's rest lines against its mesh (mesh units).

    ``inside``: the fraction of the lines' length inside the mesh; ``mean``: the
    mean distance outside it along the lines; ``near``: the
    distance outside it that a quarter of the length is within (0 when a quarter or
    more runs inside: a line that runs along its muscle); ``far``: the farthest point's
    distance; ``length``: the lines' longest; ``extent``: the mesh's longest
    principal extent.
    """

    inside: float
    mean: float
    near: float
    far: float
    length: float
    extent: float


def line_fit(
    V: FloatArray, F: IntArray, lines: dict[str, FloatArray], *, cache: Path | None = None
) -> LineFit:
    """The `LineFit` of rest ``lines`` (name -> (k, 3) points) to the mesh ``V, F``.

    ``cache``: as `outside_distance`'s.
    """
    return line_fits(V, F, [lines], cache=cache)[0]


def line_fits(
    V: FloatArray, F: IntArray, many: list[dict[str, FloatArray]], *, cache: Path | None = None
) -> list[LineFit]:
    """`line_fit` of several sets of lines to one mesh (one distance query for all)."""
    V = np.asarray(V, dtype=np.float64)
    X = V - V.mean(axis=0)
    axes = np.linalg.svd(X, full_matrices=False)[2]
    extent = float(np.ptp(X @ axes[0]))
    step = extent / 200
    pts = [np.vstack([resample_polyline(L, step) for L in lines.values()]) for lines in many]
    d_all = outside_distance(np.vstack(pts), V, F, cache=cache)
    out = []
    start = 0
    for lines, P in zip(many, pts, strict=True):
        d = d_all[start : start + len(P)]
        start += len(P)
        length = max(
            float(np.linalg.norm(np.diff(L, axis=0), axis=1).sum()) for L in lines.values()
        )
        out.append(
            LineFit(
                inside=float(np.mean(d == 0)),
                mean=float(d.mean()),
                near=float(np.quantile(d, 0.25)),
                far=float(d.max()),
                length=length,
                extent=extent,
            )
        )
    return out

"""The page's state: arrays as the page decodes them, colours, the pose asked for.

What both of the viewer's sources (`._sources`) and its app (`._app`) put in the trame
state: positions, triangles and poly-lines as the bytes of typed arrays (binary in the
server's messages; the page views them as their types, ``window.mw.typed``), colours as
RGB, the time line's words.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..constants import defaults

__all__ = [
    "CONTACT_STOPS",
    "Lighter",
    "Request",
    "cells",
    "contact_colours",
    "css_rgb",
    "encode",
    "lighter_parts",
    "points",
    "polylines",
    "time_text",
]


@dataclass
class Request:
    """A pose the page asks for: the sliders' ``values``, or ``frame`` of the motion."""

    kind: str  # "values" or "frame"
    values: dict[str, float] = field(default_factory=dict)
    frame: int | None = None
    id: int = 0
    moving: bool = False  # a slider moving (drawn lighter until it stops)


@dataclass(frozen=True)
class Lighter:
    """A surface drawn lighter while a slider moves: some of its vertices, their triangles.

    ``keep``: rows of the full surface's vertices (decimation that removes vertices, never
    moves one: vtk's DecimatePro without splitting), ``faces``: triangles over them. The
    positions shown are the full pose's own, ``V[keep]``.
    """

    keep: np.ndarray
    faces: np.ndarray
    full: int  # the full surface's triangles

    @classmethod
    def of(cls, V: np.ndarray, F: np.ndarray, reduction: float) -> Lighter:
        """``F`` over ``V`` with about ``reduction`` of its triangles removed."""
        import pyvista as pv
        from scipy.spatial import cKDTree

        V = np.asarray(V, dtype=np.float64)
        F = np.asarray(F, dtype=np.int64)
        if reduction <= 0.0 or len(F) < 100:
            return cls(np.arange(len(V)), F, len(F))
        d = pv.PolyData.from_regular_faces(V, F).decimate_pro(reduction, preserve_topology=True)
        faces = np.asarray(d.regular_faces, dtype=np.int64)
        # the kept vertices are the full surface's own (the nearest: at distance 0)
        _, keep = cKDTree(V).query(np.asarray(d.points, dtype=np.float64))
        return cls(np.asarray(keep, dtype=np.int64), faces, len(F))


def lighter_parts(
    meshes: dict[str, tuple[np.ndarray, np.ndarray]], budget: int | None = None
) -> dict[str, Lighter]:
    """Each part's `Lighter`, about ``budget`` triangles in all.

    ``budget``: ``defaults.view_moving_triangles`` unless given. Every part keeps the same
    share of its triangles (at least a tenth); none where the whole scene is within the
    budget already.
    """
    budget = defaults.view_moving_triangles if budget is None else budget
    total = sum(len(F) for _, F in meshes.values())
    keep = min(1.0, max(0.1, budget / max(total, 1)))
    if keep >= 1.0:
        return {}
    return {k: Lighter.of(V, F, 1.0 - keep) for k, (V, F) in meshes.items()}


def time_text(times: FloatArray, n_frames: int, k: int) -> str:
    """The time slider's words for frame ``k``."""
    t = float(times[k]) if len(times) else 0.0
    return f"frame {k} of {n_frames - 1}, t = {t:.3f} s"


def css_rgb(c: np.ndarray) -> str:
    """A colour (RGB in 0-1) as CSS writes it."""
    r, g, b = np.rint(255.0 * np.asarray(c)).astype(int)
    return f"rgb({r}, {g}, {b})"


#: the contact colouring: black (touching), red halfway, yellow at
#: ``defaults.view_contact_reach`` and beyond
CONTACT_STOPS = np.array([[0.0, 0.0, 0.0], [0.9, 0.0, 0.0], [0.9, 0.9, 0.0]])


def contact_colours(distance: np.ndarray) -> np.ndarray:
    """Each distance's colour: (k, 3) uint8 (mesh units, clipped to ``defaults.view_contact_reach``)."""
    u = (
        np.clip(np.asarray(distance, dtype=np.float64), 0.0, defaults.view_contact_reach)
        / defaults.view_contact_reach
    )
    at = np.linspace(0.0, 1.0, len(CONTACT_STOPS))
    rgb = np.column_stack([np.interp(u, at, CONTACT_STOPS[:, k]) for k in range(3)])
    return np.rint(255.0 * rgb).astype(np.uint8)


def encode(a: np.ndarray, dtype: Any) -> bytes | list[Any]:
    """An array in the form the page decodes: its bytes as ``dtype`` (binary on the wire).

    The page's bindings view them as the type their part needs (``window.mw.typed``:
    float32 positions, uint32 cells, uint8 colours as they are). An empty one as an
    empty list (vtk.js takes a list as it is).
    """
    b = np.ascontiguousarray(a, dtype=dtype).ravel()
    if not b.size:
        return []
    return b.tobytes()


def cells(F: np.ndarray) -> bytes | list[Any]:
    """Cells (k, n) in VTK's legacy form: ``n, i0, ..., n, i0, ...``."""
    F = np.asarray(F)
    if not len(F):
        return encode(np.zeros(0), np.uint32)
    return encode(np.column_stack([np.full(len(F), F.shape[1]), F]), np.uint32)


def points(P: np.ndarray) -> bytes | list[Any]:
    P = np.where(np.isfinite(P), P, 0.0)
    return encode(P, np.float32)


def polylines(
    lines: list[np.ndarray],
) -> tuple[bytes | list[Any], bytes | list[Any]]:
    """Poly-lines as one point array and one cell array."""
    if not lines:
        return points(np.zeros((0, 3))), encode(np.zeros(0), np.uint32)
    P = np.vstack(lines)
    cells, o = [], 0
    for pts in lines:
        cells += [len(pts), *range(o, o + len(pts))]
        o += len(pts)
    return points(P), encode(np.array(cells), np.uint32)

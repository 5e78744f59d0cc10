"""The page's state: arrays as the page decodes them, colours, the pose asked for.

What both of the viewer's sources (`._sources`) and its app (`._app`) put in the trame
state: positions, triangles and poly-lines as the bytes of typed arrays (binary in the
server's messages; the page views them as their types, ``window.mw.typed``), colours as
RGB, the time line's words.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..constants import defaults

__all__ = [
    "CONTACT_STOPS",
    "Drawn",
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


#: a part's positions, or a function that gives them
Positions = np.ndarray | Callable[[], np.ndarray]


def _positions(P: Positions) -> np.ndarray:
    return P() if callable(P) else P


class Drawn:
    """The positions the page has of each surface, in full and lighter (`Lighter`).

    Both of the viewer's sources put their surfaces' positions through it: while a slider
    moves (``moving``) a part's lighter positions are sent and its full ones kept back
    until `still`; otherwise the full ones. ``token`` says what makes a part's positions
    differ from the ones sent (a bone's transform, or its file): the same token, nothing
    sent; None, always sent (a muscle).
    """

    def __init__(self) -> None:
        self.light: dict[str, Lighter] = {}  # per part ("muscle0", "bone1")
        self._sent: dict[str, Any] = {}  # per part: the token of its full positions sent
        self._sent_light: dict[str, Any] = {}
        self._held: dict[str, tuple[np.ndarray, Any]] = {}  # full positions kept back
        self.shown_light = False  # the pose shown last was drawn lighter

    def begin(self, moving: bool) -> bool:
        """A pose to draw: whether lighter (a slider moving, and lighter surfaces made)."""
        self.shown_light = moving and bool(self.light)
        return self.shown_light

    def put(self, up: dict[str, Any], key: str, P: Positions, token: Any = None) -> None:
        """Part ``key``'s positions into the state update ``up``, as this pose is drawn.

        ``P``: the positions, or a function that gives them (called only where sent).
        """
        if self.shown_light and key in self.light:
            if token is None or self._sent_light.get(key) != token:
                up[f"{key}_lp"] = points(_positions(P)[self.light[key].keep])
                self._sent_light[key] = token
            if token is None or self._sent.get(key) != token:
                self._held[key] = (P, token)
            else:  # back where the page's full positions are
                self._held.pop(key, None)
            return
        self._held.pop(key, None)
        if token is None or self._sent.get(key) != token:
            up[f"{key}_p"] = points(_positions(P))
            self._sent[key] = token

    def colours(self, up: dict[str, Any], key: str, rgb: np.ndarray) -> None:
        """Part ``key``'s colours (RGB, uint8) into ``up``, full and lighter."""
        up[f"{key}_c"] = encode(rgb, np.uint8)
        if key in self.light:
            up[f"{key}_lc"] = encode(rgb[self.light[key].keep], np.uint8)

    def make_light(
        self, meshes: dict[str, tuple[np.ndarray, np.ndarray]], now: dict[str, tuple[Any, Any]]
    ) -> dict[str, Any]:
        """The lighter surfaces (`lighter_parts` of ``meshes``), with the positions ``now``.

        ``now[key]``: the part's positions shown and their token. Returns the state that
        draws them: their triangles, positions and the page's words (empty: none needed).
        """
        self.light = lighter_parts(meshes)
        if not self.light:
            return {}
        up: dict[str, Any] = {f"{k}_lf": cells(L.faces) for k, L in self.light.items()}
        drawn = sum(len(L.faces) for L in self.light.values())
        full = sum(L.full for L in self.light.values())
        up["light_note"] = (
            f"drawn with {drawn:,} of {full:,} triangles while a slider moves; all when it stops"
        )
        for k, (P, token) in now.items():
            if k in self.light:
                up[f"{k}_lp"] = points(_positions(P)[self.light[k].keep])
                self._sent_light[k] = token
        return up

    def still(self) -> dict[str, Any]:
        """The full positions kept back while a slider moved (empty: the page has them)."""
        if not self.shown_light:
            return {}
        self.shown_light = False
        up: dict[str, Any] = {"light": False}
        for key, (P, token) in self._held.items():
            up[f"{key}_p"] = points(_positions(P))
            self._sent[key] = token
        self._held.clear()
        return up


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

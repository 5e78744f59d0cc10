"""Which side of an obstacle a muscle's vertices belong on: from an earlier state of its path.

The nearest way out of a bone is the wrong one for a vertex that went in deeper than
half the bone's thickness, or passed through a thin part of it: the iliac wing, the
ischial tuberosity at deep hip flexion. Which side is right is a matter of history
(the muscle came from somewhere): IPC (Li et al. 2020) keeps it by continuous
collision detection along the way from an intersection-free start. Here each pose is
solved from an earlier state of a path from the rest pose (`SideReference`: the rest
pose itself, or a waypoint of the path, see `musclewrap.scene`), and a vertex whose
outward direction now points against the one it had then has crossed the surface on
the way: it is taken back to where its straight way from then to now first entered
the obstacle (the continuous collision test of that segment, `Obstacle.first_entry`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from ..constants import defaults
from ._placed import Placed

__all__ = ["SideReference", "on_their_side", "passed_through"]


class SideReference:
    """A muscle's earlier state on the same path, placed against the same obstacles.

    Parameters
    ----------
    positions : (n, 3) float64 array, or callable
        The fine vertices' positions in that state, in the muscle's frame then;
        or a function of no argument that gives them, called when first needed
        (``W @ x`` for a cage state ``x``: a reference no pose asks costs nothing).
    placed : sequence of Placed
        The obstacles as they were placed in that state, in the order of the
        pose solved now.
    n : int, optional
        Number of vertices (needed with a callable ``positions``).

    Notes
    -----
    Per obstacle, every vertex's position in the obstacle's frame, and per vertex
    the outward direction of the obstacle there, are computed once, when first
    asked for (`at`), and kept: every pose that takes its sides from this state
    asks for much the same vertices.
    """

    def __init__(
        self,
        positions: FloatArray | Callable[[], FloatArray],
        placed: Sequence[Placed],
        n: int | None = None,
    ) -> None:
        if callable(positions):
            if n is None:
                raise ValueError("SideReference: give n with a callable positions")
            self._whole = positions
        else:
            P = np.asarray(positions, dtype=np.float64)
            n = len(P)
            self._whole = lambda: P
        self.n = int(n)
        self.placed = tuple(placed)
        # per obstacle, made when first asked for: known, directions
        self._kept: list[tuple[npt.NDArray[np.bool_], FloatArray, FloatArray] | None] = [
            None for _ in self.placed
        ]  # per obstacle: known, directions, signed distances
        self._lower: list[FloatArray | None] = [None for _ in self.placed]
        self._all: FloatArray | None = None  # every vertex then (muscle frame), when needed
        self._frames: list[FloatArray | None] = [None for _ in self.placed]
        self._approach: dict[
            tuple[int, float], tuple[IntArray, FloatArray, FloatArray, FloatArray]
        ] = {}

    def at(self, b: int, rows: IntArray) -> tuple[FloatArray, FloatArray]:
        """Positions and outward directions of vertices ``rows`` against obstacle ``b`` then.

        Both in the obstacle's own frame: the position of each vertex in that
        state and the unit direction from its closest point on the obstacle to
        it: the grid's gradient where the grid holds exact values around it (near
        the obstacle), else the closest point's (an exact query; the pseudo-normal
        where it lies on the surface).
        """
        rows = np.asarray(rows, dtype=np.int64)
        self._known(b, rows)
        kept = self._kept[b]
        assert kept is not None
        return self.positions(b, rows), kept[1][rows]

    def inside(self, b: int, rows: IntArray) -> npt.NDArray[np.bool_]:
        """Whether vertices ``rows`` were inside obstacle ``b`` then, deeper than a set depth.

        A vertex inside then (a kept rest overlap, or a waypoint that left it there) has
        no side it came from. One on the surface then (a contact, at the margin: its
        interpolated distance a hair below 0) keeps its side. How deep counts as inside:
        `defaults.side_inside_spacings` of the bone's grid spacings.
        """
        rows = np.asarray(rows, dtype=np.int64)
        self._known(b, rows)
        kept = self._kept[b]
        assert kept is not None
        return kept[2][rows] < -defaults.side_inside_spacings * self.placed[b].obstacle.h

    def _known(self, b: int, rows: IntArray) -> None:
        """The directions and signed distances then of vertices ``rows``, found once each."""
        kept = self._kept[b]
        if kept is None:
            kept = self._kept[b] = (
                np.zeros(self.n, dtype=bool), np.empty((self.n, 3)), np.empty(self.n)
            )  # fmt: skip
        known, direction, phi = kept
        todo = np.unique(rows[~known[rows]])
        if len(todo):
            ob = self.placed[b].obstacle
            Q = self.positions(b, todo)
            got, ph, G = ob.interpolate(Q, np.inf)
            direction[todo[got]] = G
            phi[todo[got]] = ph
            rest = np.ones(len(todo), dtype=bool)
            rest[got] = False
            if rest.any():
                ph, _, G = ob.signed(Q[rest])
                direction[todo[rest]] = G
                phi[todo[rest]] = ph
            known[todo] = True

    def positions(self, b: int, rows: IntArray) -> FloatArray:
        """Positions of vertices ``rows`` then, in obstacle ``b``'s frame."""
        if self._frames[b] is None:
            if self._all is None:
                self._all = self._whole()
            self._frames[b] = np.ascontiguousarray(self.placed[b].to_obstacle(self._all))
        Q = self._frames[b]
        assert Q is not None
        return Q[rows]

    def were_near(self, b: int, reach: float) -> tuple[IntArray, FloatArray]:
        """The vertices that may have been within ``reach`` of obstacle ``b`` then.

        By the grid's lower bounds of their signed distance then (computed once
        per obstacle). Returns their rows and those bounds.
        """
        if self._lower[b] is None:
            Q = self.positions(b, np.arange(self.n))
            self._lower[b] = self.placed[b].obstacle.bounds(Q)[0]
        lower = self._lower[b]
        assert lower is not None
        rows = np.flatnonzero(lower < reach)
        return rows, lower[rows]

    def approaching(self, b: int, P: FloatArray, reach: float, thickness: float = 0.0) -> IntArray:
        """The vertices ``P`` (now, muscle frame) that may have come through obstacle ``b``.

        Those that may have been within ``reach`` of it then (`were_near`) and have
        moved toward it, against its outward direction then (the grid's gradient
        there), by more than their distance from it then and ``thickness``: a
        vertex that lifted off, or slid along it, cannot have come through a part of
        it at least that thick. Cheap: what depends only on then is kept per
        obstacle and reach.
        """
        key = (b, float(reach))
        if key not in self._approach:
            rows, lower = self.were_near(b, reach)
            ref_q = self.positions(b, rows)
            got, _, ref_d = self.placed[b].obstacle.interpolate(ref_q, reach)
            self._approach[key] = (rows[got], lower[got], ref_q[got], ref_d)
        rows, lower, ref_q, ref_d = self._approach[key]
        if not len(rows):
            return rows
        Q = self.placed[b].to_obstacle(P[rows])
        return rows[np.einsum("ij,ij->i", Q - ref_q, ref_d) < -lower - thickness]


def passed_through(
    pl: Placed,
    reference: SideReference,
    b: int,
    P: FloatArray,
    handled: IntArray,
    reach: float,
    thickness: float = 0.0,
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Vertices that came through obstacle ``b`` and have left it on its far side.

    Of the vertices ``P`` (all, muscle frame) that may have come through the
    obstacle since ``reference`` (`SideReference.approaching`: they were within
    ``reach`` of it then and moved toward it by more than their distance and
    ``thickness``, the thinnest part of it that counts) and
    are not ``handled`` already (the ones near it now), those whose straight way
    from then to now enters it (`on_their_side`). Returns their rows, their
    signed distance from the tangent plane where they entered (negative: beyond
    it) and its outward direction, in the obstacle's frame.
    """
    rows = reference.approaching(b, P, reach, thickness)
    if len(rows) and len(handled):
        # a mask, not np.isin (which sorts both): the vertices number thousands, both sets
        # hundreds to thousands, several times a pose
        seen = np.zeros(len(P), dtype=bool)
        seen[handled] = True
        rows = rows[~seen[rows]]
    if not len(rows):
        return rows, np.zeros(0), np.zeros((0, 3))
    Q = np.ascontiguousarray(pl.to_obstacle(P[rows]))
    phi, C, N = pl.obstacle.signed(Q)
    phi, _, N, turned = on_their_side(pl, reference, b, rows, Q, phi, C, N)
    return rows[turned], phi[turned], N[turned]


def on_their_side(
    pl: Placed,
    reference: SideReference,
    b: int,
    rows: IntArray,
    Q: FloatArray,
    phi: FloatArray,
    C: FloatArray | None,
    N: FloatArray,
) -> tuple[FloatArray, FloatArray | None, FloatArray, IntArray]:
    """Linearise each vertex against the obstacle on the side it came from.

    ``Q`` are the vertices ``rows`` now, in obstacle ``b``'s frame, with their
    signed distance ``phi``, closest points ``C`` (or None) and outward
    directions ``N`` (from a query: exact or the grid's). A vertex whose direction points against
    the one it had in ``reference`` (negative dot product) lies beyond the
    obstacle from where it was: its straight way from then to now (in the
    obstacle's frame) is tested for where it first enters the obstacle, and that
    point and its outward direction replace ``C`` and ``N``, with ``phi`` its
    signed distance from the tangent plane there (negative: behind it). A
    vertex whose way does not enter (it went round the obstacle's edge) keeps its
    nearest point.

    Returns the new ``phi, C, N`` (copies) and the positions (into ``rows``)
    that were turned.
    """
    ref_q, ref_d = reference.at(b, rows)
    flip = np.flatnonzero(np.einsum("ij,ij->i", N, ref_d) < 0.0)
    # a vertex inside the obstacle then (a kept rest overlap) came from no side of it
    flip = flip[~reference.inside(b, rows[flip])]
    if not len(flip):
        return phi, C, N, flip
    found, E, NE = pl.obstacle.first_entry(ref_q[flip], Q[flip])
    hit = np.flatnonzero(found)
    turned = flip[hit]
    plane = np.einsum("ij,ij->i", Q[turned] - E[hit], NE[hit])
    # A vertex inside that the entry's tangent plane puts less deep than its nearest way out
    # does is not one that went past the middle of a thin part (that one lies deeper behind
    # the plane than the far side is near): it slid along or round the bone since then (a
    # vertex inside a cartilage's shell of 2-4 mm, moved 11 mm sideways from where it was,
    # which the plane put in front of itself and nothing took out). It keeps the nearest way.
    keep = (phi[turned] >= 0.0) | (plane <= phi[turned])
    turned, hit, plane = turned[keep], hit[keep], plane[keep]
    if not len(turned):
        return phi, C, N, turned
    phi, N = phi.copy(), N.copy()
    if C is not None:
        C = C.copy()
        C[turned] = E[hit]
    N[turned] = NE[hit]
    phi[turned] = plane
    return phi, C, N, turned

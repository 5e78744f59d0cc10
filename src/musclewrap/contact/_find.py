"""Finding contacts and stating them as linear conditions on the fine vertices."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._typing import FloatArray, IntArray
from ._near import Near
from ._placed import Placed
from ._sides import SideReference, on_their_side, passed_through

__all__ = ["contact_candidates"]


def contact_candidates(
    P: FloatArray,
    placed: Sequence[Placed],
    margin: float,
    band: float,
    near: Near,
    sides: SideReference | None = None,
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Vertices within ``band`` of the margin of an obstacle: index, gap, outward direction.

    ``gap`` is the signed distance less the allowed one (negative: too near),
    from the obstacle's grid (`Obstacle.interpolate`, approximate); the
    directions are unit vectors in the muscle's frame. A vertex near two
    obstacles appears twice. With ``sides``, a vertex that has come through the
    obstacle from where it was there is linearised at the point where it
    entered (`on_their_side`), its gap measured from the tangent plane there;
    also one that went through a thin part of it and is now beyond it by more
    than the grid holds exact values (`passed_through`).
    """
    out_i, out_g, out_n = [], [], []
    for b, (pl, r, allowed) in enumerate(
        zip(placed, near.rows(P, band), near.allowed, strict=True)
    ):
        # the grid's interpolated distance: linearised conditions need no exact one
        Q = pl.to_obstacle(P[r])
        if len(r):
            idx, phi, N = pl.obstacle.interpolate(Q, margin + band)
        else:  # none near: empty, in the shapes a vertex come through below joins
            idx, phi, N = r, np.zeros(0), np.zeros((0, 3))
        if sides is not None and len(idx):
            phi, _, N, _ = on_their_side(pl, sides, b, r[idx], Q[idx], phi, None, N)
        idx = r[idx]
        if sides is not None:
            # past a part of it a quarter of the band thick or more (a thinner one is
            # passed between the muscle's vertices)
            far, far_phi, far_N = passed_through(pl, sides, b, P, idx, margin + band, 0.25 * band)
            if len(far):
                idx = np.concatenate([idx, far])
                phi = np.concatenate([phi, far_phi])
                N = np.vstack([N, far_N])
        if not len(idx):
            continue
        gap = phi - allowed[idx]
        close = gap < band
        out_i.append(idx[close])
        out_g.append(gap[close])
        out_n.append(pl.to_muscle(N[close], direction=True))
    if not out_i:
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 3))
    return np.concatenate(out_i), np.concatenate(out_g), np.concatenate(out_n)

"""The rest pose against the bones: a muscle's overlap pushed out once, its attachments."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..constants import defaults
from ..mesh import mean_edge_length, self_intersecting_faces, vertex_adjacency, volume
from ._finish import ContactReport, push_out
from ._placed import Placed

__all__ = ["anchors_at_rest", "attachment_patches", "kept_allowance", "rest_push_out"]


def rest_push_out(
    V: FloatArray, F: IntArray, placed: Sequence[Placed], margin: float
) -> tuple[FloatArray | None, ContactReport, str]:
    """A muscle pushed out of its bones at the rest pose, volume-exact, without folding.

    First with the bones' vertices taken out of the muscle as well (`push_out` with
    ``bone_vertices``: seconds, and it can fold the surface where a bone's edge is
    thin), then with the muscle's vertices alone; a result whose surface passes
    through itself is not used.

    Returns
    -------
    P : (n, 3) float64 array or None
        The positions (None: every variant folded the surface).
    report : ContactReport
        The last push-out's (``rounds == 0``: nothing overlapped).
    how : {"bone vertices", "vertices", "none"}
        Which variant was used ("none": P is None).
    """
    rep = None
    for how in ("bone vertices", "vertices"):
        P, rep = push_out(
            V, F, placed, volume_target=volume(V, F), margin=margin,
            bone_vertices=how == "bone vertices",
        )  # fmt: skip
        if rep.rounds == 0 or not rep.ok or self_intersecting_faces(P, F) == 0:
            return P, rep, how
    assert rep is not None
    return None, rep, "none"


def kept_allowance(
    pl: Placed,
    V: FloatArray,
    margin: float,
    F: IntArray | None = None,
    rings: int | None = None,
) -> FloatArray | None:
    """A kept rest overlap: each vertex nearer the bone than the margin may stay as near.

    With the muscle's triangles ``F``, each vertex may go as near as the nearest of
    its neighbours within ``rings`` (default ``defaults.kept_overlap_rings``) was: a
    muscle slides a little along its bones through a motion, and a vertex the kept
    overlap's rim slid onto would otherwise be pushed out of a bone its neighbour may
    stay in (a step the cage cannot take, which the fine finish creases). Returns the
    allowance per vertex (`Placed.allowance`), None where no vertex is nearer than the
    margin.
    """
    idx, phi, _, _ = pl.obstacle.query(pl.to_obstacle(V), margin)
    if not len(idx):
        return None
    a = np.full(len(V), np.inf)
    a[idx] = phi
    rings = defaults.kept_overlap_rings if rings is None else rings
    if F is not None and rings > 0:
        A = vertex_adjacency(F, len(V)).tocsr()
        has = np.diff(A.indptr) > 0
        for _ in range(rings):
            near = np.full(len(V), np.inf)
            near[has] = np.minimum.reduceat(a[A.indices], A.indptr[:-1][has])
            a = np.minimum(a, near)
    return a


def anchors_at_rest(
    V: FloatArray,
    F: IntArray,
    own: Sequence[Placed],
    lines: Mapping[str, FloatArray],
    margin: float,
) -> IntArray:
    """The vertices where a muscle starts on a bone of its own body (its origin).

    The vertices within ``defaults.anchor_reach`` mean edge lengths of the margin
    of one of the bones ``own`` (those carried by the muscle's body) at rest, in
    patches near an end of an action line (`attachment_patches`).
    """
    reach = margin + defaults.anchor_reach * mean_edge_length(V, F)
    found = [pl.obstacle.query(pl.to_obstacle(V), reach)[0] for pl in own]
    return attachment_patches(
        vertex_adjacency(F, len(V)),
        V,
        np.concatenate(found) if found else np.zeros(0, np.int64),
        lines,
    )


def attachment_patches(
    A: sp.csr_matrix,
    V: FloatArray,
    candidates: IntArray,
    lines: Mapping[str, FloatArray],
    reach: float = defaults.anchor_end_reach,
) -> IntArray:
    """The candidates that form an attachment: patches near the end of an action line.

    ``candidates`` (vertices lying on a bone of the muscle's own body at rest)
    split into patches connected on the mesh (adjacency ``A``). A patch is kept
    when its nearest vertex is within ``reach`` times a path's length of that
    path's first or last point: where the muscle starts on the bone (its
    origin). A patch far from every end is a bone the muscle lies on and slides
    over through a motion (the psoas on the pelvic brim); holding it in place
    would crease the muscle there.

    Parameters
    ----------
    A : scipy.sparse.csr_matrix
        Vertex adjacency of the muscle's mesh.
    V : (n, 3) float64 array
        Rest positions, in the frame of ``lines``.
    candidates : (k,) int array
    lines : mapping of str to (p, 3) arrays
        The rest action lines.
    reach : float, optional
        Fraction of a path's length.

    Returns
    -------
    (j,) int64 array
        The kept candidates, sorted.
    """
    from scipy.sparse.csgraph import connected_components

    c = np.unique(np.asarray(candidates, dtype=np.int64))
    if not len(c):
        return c
    _, label = connected_components(A[c][:, c], directed=False)
    near = np.zeros(len(c), dtype=bool)
    for pts in lines.values():
        pts = np.asarray(pts, dtype=np.float64)
        length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        for end in (pts[0], pts[-1]):
            near |= np.linalg.norm(V[c] - end, axis=1) <= reach * length
    return np.sort(c[np.isin(label, np.unique(label[near]))])

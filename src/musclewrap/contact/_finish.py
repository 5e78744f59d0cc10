"""The fine-level contact finish: muscle vertices out of obstacles, the fine volume exact."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._typing import FloatArray, IntArray
from ..constants import defaults, tol
from ..mesh import (
    barycentric,
    cubic_root_near,
    in_box,
    mean_edge_length,
    mean_rows,
    umbrella_laplacian,
    vertex_adjacency,
    vertex_normals,
    volume,
    volume_cubic,
)
from ._inside import Inside, bone_vertices_inside
from ._near import Near
from ._placed import Placed
from ._sides import SideReference, on_their_side

__all__ = [
    "ContactReport",
    "longest_pushes",
    "nudge",
    "push_out",
    "rings",
    "triangle_pushes",
    "unfold",
    "vertex_faces",
]


@dataclass(frozen=True)
class ContactReport:
    """What the contact finish did to one pose.

    Attributes
    ----------
    contact_vertices : int
        Vertices in contact in the result: within twice ``tol.contact`` mean
        edge lengths of the margin of an obstacle.
    depth_before : float
        Deepest vertex inside an obstacle before the finish (0 if none), mesh units.
    depth_after : float
        Deepest vertex inside an obstacle after it (0 if none): exact.
    moved_max : float
        Largest displacement of a vertex by the finish.
    rounds : int
        Push-out rounds (0: nothing to do).
    ok : bool
        Whether every vertex keeps the margin (to ``tol.contact`` mean edge lengths).
    reason : str
        Why it is not ok, naming the obstacle; empty when ok.
    inside : int
        Vertices inside an obstacle after the finish (exact; a kept rest
        overlap may leave some).
    bone_inside : int
        Obstacle vertices inside the muscle after the finish (exact, among those
        near it: `bone_vertices_inside`); 0 where they were not looked for.
    bone_inside_depth : float
        The deepest of them (0 if none).
    """

    contact_vertices: int = 0
    depth_before: float = 0.0
    depth_after: float = 0.0
    moved_max: float = 0.0
    rounds: int = 0
    ok: bool = True
    reason: str = ""
    inside: int = 0
    bone_inside: int = 0
    bone_inside_depth: float = 0.0


def rings(A: sp.csr_matrix, seeds: np.ndarray, k: int) -> np.ndarray:
    """Ring distance (in edges) from the ``seeds`` of every vertex up to ``k``; k + 1 beyond."""
    level = np.full(A.shape[0], k + 1, dtype=np.int64)
    _rings_kernel(A.indptr, A.indices, np.asarray(seeds, dtype=np.int64), k, level)
    return level


@numba.njit(cache=True)
def _rings_kernel(indptr, indices, seeds, k, level):  # noqa: ANN001, ANN202 # pragma: no cover
    # breadth-first search over the CSR adjacency, k levels deep
    front = np.empty(level.shape[0], dtype=np.int64)
    n_front = 0
    for s in seeds:
        if level[s] != 0:
            level[s] = 0
            front[n_front] = s
            n_front += 1
    nxt = np.empty(level.shape[0], dtype=np.int64)
    for r in range(1, k + 1):
        n_next = 0
        for q in range(n_front):
            v = front[q]
            for p in range(indptr[v], indptr[v + 1]):
                w = indices[p]
                if level[w] > k:
                    level[w] = r
                    nxt[n_next] = w
                    n_next += 1
        if n_next == 0:
            break
        front, nxt = nxt, front
        n_front = n_next


@numba.njit(cache=True)
def _smooth(indptr, indices, D, rows, sweeps, keep):  # noqa: ANN001, ANN202 # pragma: no cover
    # Jacobi sweeps on the given rows: D_v <- keep D_v + (1 - keep) mean of its 1-ring
    new = np.empty((rows.shape[0], 3))
    for _ in range(sweeps):
        for q in range(rows.shape[0]):
            v = rows[q]
            s0 = s1 = s2 = 0.0
            for p in range(indptr[v], indptr[v + 1]):
                w = indices[p]
                s0 += D[w, 0]
                s1 += D[w, 1]
                s2 += D[w, 2]
            k = indptr[v + 1] - indptr[v]
            new[q, 0] = keep * D[v, 0] + (1.0 - keep) * s0 / k
            new[q, 1] = keep * D[v, 1] + (1.0 - keep) * s1 / k
            new[q, 2] = keep * D[v, 2] + (1.0 - keep) * s2 / k
        for q in range(rows.shape[0]):
            v = rows[q]
            D[v, 0], D[v, 1], D[v, 2] = new[q, 0], new[q, 1], new[q, 2]


@numba.njit(cache=True)
def _rows3(indptr, indices, data, v, out):  # noqa: ANN001, ANN202 # pragma: no cover
    # out = M v for the CSR matrix M on (rows, 3) arrays flattened, as scipy's product sums
    for r in range(indptr.shape[0] - 1):
        s0 = s1 = s2 = 0.0
        for p in range(indptr[r], indptr[r + 1]):
            j = 3 * indices[p]
            s0 += data[p] * v[j]
            s1 += data[p] * v[j + 1]
            s2 += data[p] * v[j + 2]
        out[3 * r], out[3 * r + 1], out[3 * r + 2] = s0, s1, s2


@numba.njit(cache=True)
def _plate_product(  # noqa: PLR0913
    up, ui, ud, tp, ti, td, cp, ci, cd, kp, ki, kd, on, w, v, tmp, cx, out
):  # noqa: ANN001, ANN202 # pragma: no cover
    # out = (I3 (x) Us^T Us + 1e-9) v + w C^T (on * C v), in the order scipy's products take
    _rows3(up, ui, ud, v, tmp)
    for c in range(cp.shape[0] - 1):
        s = 0.0
        for p in range(cp[c], cp[c + 1]):
            s += cd[p] * v[ci[p]]
        cx[c] = on[c] * s
    _rows3(tp, ti, td, tmp, out)
    for i in range(v.shape[0]):
        s = 0.0
        for p in range(kp[i], kp[i + 1]):
            s += kd[p] * cx[ki[p]]
        out[i] = out[i] + 1e-9 * v[i] + w * s


@numba.njit(cache=True)
def _plate_cg_kernel(  # noqa: PLR0913
    up, ui, ud, tp, ti, td, cp, ci, cd, kp, ki, kd, on, w, b, x0, jac, maxiter, rtol
):  # noqa: ANN001, ANN202 # pragma: no cover
    # Jacobi-preconditioned conjugate gradients on (I3 (x) Us^T Us + 1e-9 + w C^T on C) x = b,
    # from x0, as scipy's `cg` iterates (its stop: |r| < rtol |b|); `_plate`'s matrix-free
    # system, its products over the CSR arrays of Us (up, ui, ud), Us^T (tp, ...), C, C^T
    n = b.shape[0]
    x = np.empty(n)
    tmp = np.empty(3 * (up.shape[0] - 1))
    cx = np.empty(cp.shape[0] - 1)
    q = np.empty(n)
    r = np.empty(n)
    z = np.empty(n)
    d = np.empty(n)
    bnrm = 0.0
    nonzero = False
    for i in range(n):
        x[i] = x0[i]
        bnrm += b[i] * b[i]
        nonzero = nonzero or x0[i] != 0.0
    if bnrm == 0.0:
        for i in range(n):
            x[i] = b[i]
        return x
    atol = rtol * np.sqrt(bnrm)
    if nonzero:
        _plate_product(up, ui, ud, tp, ti, td, cp, ci, cd, kp, ki, kd, on, w, x, tmp, cx, q)
        for i in range(n):
            r[i] = b[i] - q[i]
    else:
        for i in range(n):
            r[i] = b[i]
    rho_prev = 1.0
    for it in range(maxiter):
        rn = 0.0
        for i in range(n):
            rn += r[i] * r[i]
        if np.sqrt(rn) < atol:
            break
        rho = 0.0
        for i in range(n):
            z[i] = jac[i] * r[i]
            rho += r[i] * z[i]
        beta = rho / rho_prev if it > 0 else 0.0
        for i in range(n):
            d[i] = beta * d[i] + z[i] if it > 0 else z[i]
        _plate_product(up, ui, ud, tp, ti, td, cp, ci, cd, kp, ki, kd, on, w, d, tmp, cx, q)
        dq = 0.0
        for i in range(n):
            dq += d[i] * q[i]
        alpha = rho / dq
        for i in range(n):
            x[i] += alpha * d[i]
            r[i] -= alpha * q[i]
        rho_prev = rho
    return x


def triangle_pushes(C: FloatArray, T: FloatArray, v: FloatArray) -> FloatArray:
    """The least displacements of the corners of triangles that carry points of them by ``v``.

    ``C`` (k, 3): points of the triangles ``T`` (k, 3, 3); ``v`` (k, 3). The corners
    move by their (clipped) barycentric weights ``w`` over ``|w|^2``, which moves each
    point by exactly ``v``. Returns (3 k, 3), the corners of each triangle in turn.
    """
    w = np.clip(barycentric(C, T), 0.0, None)
    w = w / np.sum(w * w, axis=1)[:, None]
    return (w[:, :, None] * v[:, None, :]).reshape(-1, 3)


def longest_pushes(push: FloatArray, size: FloatArray, verts: IntArray, disp: FloatArray) -> None:
    """Write the pushes ``disp`` of ``verts`` into ``push``, their lengths into ``size``.

    A vertex pushed more than once keeps its longest push.
    """
    norm = np.linalg.norm(disp, axis=1)
    order = np.argsort(norm)  # the longest push per vertex is written last
    push[verts[order]] = disp[order]
    size[verts[order]] = norm[order]


def _spread(
    A: sp.csr_matrix,
    hit: IntArray,
    D: FloatArray,
    edge: float,
    held: np.ndarray | None = None,
    beyond: int = 0,
) -> tuple[FloatArray, IntArray, int]:
    """The pushes ``D`` of the vertices ``hit`` spread harmonically over the rings round them.

    Jacobi sweeps of the 1-ring mean on the vertices within a radius that grows with
    the longest push (``defaults.contact_spread`` mean edges per edge pushed, at most
    12 rings), zero beyond it; the pushed vertices and the ``held`` ones stay.
    Returns the displacement of every vertex, each vertex's ring distance from
    ``hit`` (counted ``beyond`` rings past the radius), and the radius.
    """
    depth = float(np.linalg.norm(D, axis=1).max())
    radius = int(min(np.ceil(defaults.contact_spread * depth / edge) + 1, 12))
    level = rings(A, hit, radius + beyond)
    free = (level > 0) & (level <= radius)
    region = np.flatnonzero(free if held is None else free & ~held)
    Dall = np.zeros((A.shape[0], 3))
    Dall[hit] = D
    if len(region):
        _smooth(A.indptr, A.indices, Dall, region, 2 * radius * radius, 0.0)
    return Dall, level, radius


def _volume_step(P: FloatArray, F: IntArray, Z: FloatArray, volume_target: float) -> float:
    """The ``t`` that gives ``P + t Z`` the target volume (the cubic's root nearest 0; NaN if none)."""
    return cubic_root_near(volume_cubic(P - mean_rows(P), Z, F), volume_target, 0.0)


def _thin_plate(U: sp.csr_matrix, D: FloatArray, free: IntArray) -> None:
    """``D`` on the vertices ``free`` that changes the mesh's 1-ring means least, in place.

    Minimises ``sum |(U D)_i|^2`` over the free vertices and their neighbours, ``U``
    the uniform Laplacian (`musclewrap.mesh.umbrella_laplacian`: what the shape change
    measures), with ``D`` kept on every other vertex: a thin plate over ``free``,
    smooth across its rim.
    """
    rows = U[np.flatnonzero(rings(U, free, 1) <= 1)]  # the free vertices and their neighbours
    Uf = rows[:, free]
    Dk = D.copy()
    Dk[free] = 0.0
    D[free] = spla.splu((Uf.T @ Uf).tocsc()).solve(-(Uf.T @ (rows @ Dk)))


def unfold(
    V0: FloatArray,
    V: FloatArray,
    F: IntArray,
    U: sp.csr_matrix,
    shape0: FloatArray,
    shape: FloatArray,
    held: npt.NDArray[np.bool_],
    *,
    volume_target: float,
) -> FloatArray:
    """``V`` with the folds a move from ``V0`` made ironed out, away from the ``held`` vertices.

    ``U``: the mesh's uniform Laplacian (`musclewrap.mesh.umbrella_laplacian`, whose
    pattern is its adjacency's); ``shape0``, ``shape``: the shape change
    (`PreparedMuscle.shape_change`) at ``V0`` and ``V``. A fold is a vertex whose shape change the move raised by more than
    ``defaults.fold_rise`` to more than ``defaults.fold_shape`` mean edges. Over the
    rings within ``defaults.fold_rings`` of the folds (less the ``held`` vertices that
    are not folds: those the move had to put where they are; a fold among them is
    ironed too, and the fine finish puts it back out of the bone), the move's displacement is replaced by the thin
    plate that meets it round them (`_thin_plate`), and the volume restored exactly
    along the normals there. Returns ``V`` itself where there is no fold, or where the
    volume cannot be restored.
    """
    fold = (shape > defaults.fold_shape) & (shape - shape0 > defaults.fold_rise)
    if not fold.any():
        return V
    k = defaults.fold_rings
    free = np.flatnonzero((rings(U, np.flatnonzero(fold), k) <= k) & (~held | fold))
    if not len(free) or len(free) == len(V):
        return V  # nothing to iron, or nothing round it to meet (a closed mesh's whole)
    D = V - V0
    try:
        _thin_plate(U, D, free)
    except RuntimeError:  # a singular system (SuperLU): leave the step as it was
        return V
    P = V0 + D
    if not np.isfinite(P).all():
        return V
    mask = np.zeros(len(V))
    mask[free] = 1.0
    Zm = vertex_normals(P, F) * mask[:, None]
    t = _volume_step(P, F, Zm, volume_target)
    if not np.isfinite(t):
        return V
    return P + t * Zm


def vertex_faces(F: IntArray, n: int) -> tuple[IntArray, IntArray]:
    """The faces of each vertex as CSR arrays ``(indptr, indices)``."""
    flat = np.asarray(F, dtype=np.int64).ravel()
    order = np.argsort(flat, kind="stable")
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(flat, minlength=n), out=indptr[1:])
    return indptr, np.ascontiguousarray(order // 3)


def _violations(
    P: FloatArray,
    placed: Sequence[Placed],
    slack: float,
    near: Near,
    sides: SideReference | None = None,
) -> tuple[np.ndarray, FloatArray, FloatArray, list[float]]:
    """Vertices closer than the margin (less ``slack``) to an obstacle, and where they go.

    Returns the vertex indices, their targets (on the obstacle's surface at the
    margin plus ``slack``, along the shortest way out, in the muscle's frame),
    their signed distance less the allowed one (negative), and per obstacle the
    deepest vertex inside it (0 if none). A vertex too close to two obstacles
    takes the larger violation. ``near`` (`Near`) limits the queries to the
    vertices that can be that close. With ``sides``, a vertex inside that came
    through the obstacle goes back to the tangent plane where it entered
    (`on_their_side`), not out the nearest way (the cage's steps have taken the
    ones that passed through a thin part of it out of it on their side).
    """
    n = len(P)
    worst = np.full(n, np.inf)
    target = np.zeros((n, 3))
    depths = []
    for b, (pl, r) in enumerate(zip(placed, near.rows(P, slack), strict=True)):
        if not len(r):
            depths.append(0.0)
            continue
        allowed = near.allowed[b]
        lower = np.empty(len(r))
        Q = pl.to_obstacle(P[r])
        idx, phi, C, N = pl.obstacle.query(Q, allowed[r] - slack, lower)
        near.learn(b, r, P[r], lower)
        if sides is not None and len(idx):
            phi, C, N, _ = on_their_side(pl, sides, b, r[idx], Q[idx], phi, C, N)
            keep = phi < allowed[r[idx]] - slack
            idx, phi, C, N = idx[keep], phi[keep], C[keep], N[keep]
        Qi = Q[idx]
        idx = r[idx]
        depths.append(float(max(0.0, -phi.min(initial=0.0))))
        if not len(idx):
            continue
        gap = phi - allowed[idx]
        # onto the margin along the (outward) direction: the closest point's, or the
        # tangent plane's where the vertex entered
        t = pl.to_muscle(Qi - (gap - slack)[:, None] * N)
        take = gap < worst[idx]
        worst[idx[take]] = gap[take]
        target[idx[take]] = t[take]
    hit = np.flatnonzero(np.isfinite(worst))
    target = target[hit]
    if len(placed) > 1 and len(hit):
        # A target may lie in another obstacle (a crevice between two bones): project the
        # targets onto every obstacle in turn until none is too near one (alternating
        # projections walk out of the crevice).
        for _ in range(8):
            moved = False
            for b, pl in enumerate(placed):
                allowed = near.allowed[b][hit]
                # only targets that can be that near this obstacle
                gone = near.moved(b, target, hit)
                cand = np.flatnonzero(near.lower[b][hit] - gone < allowed + slack)
                if not len(cand):
                    continue
                idx, _, C, N = pl.obstacle.query(
                    pl.to_obstacle(target[cand]), allowed[cand] - slack
                )
                if len(idx):
                    idx = cand[idx]
                    target[idx] = pl.to_muscle(C + N * (allowed[idx] + slack)[:, None])
                    moved = True
            if not moved:
                break
    return hit, target, worst[hit], depths


_NONE_INSIDE = (
    np.zeros((0, 3)),
    np.zeros((0, 3)),
    np.zeros(0, np.int64),
    np.zeros(0),
    np.zeros(0, np.int64),
)


def _bone_vertices_in_muscle(
    P: FloatArray, F: IntArray, pl: Placed, depth: float
) -> tuple[FloatArray, FloatArray, IntArray, FloatArray, IntArray]:
    """Every obstacle vertex more than ``depth`` inside the muscle ``P, F`` (the rest pose).

    The obstacle's vertices in the muscle's box, inside by the generalized winding
    number of the whole muscle (robust; a tree over the muscle per call: seconds
    over a motion, so only once per muscle).

    Returns the vertices ``B`` (muscle frame), their closest points ``C``, the
    faces ``fi`` (rows of ``F``) holding them, the depths and ``B``'s rows in the
    obstacle.
    """
    import igl

    lo, hi = P.min(axis=0) - depth, P.max(axis=0) + depth
    B = pl.to_muscle(pl.obstacle.V)
    rows = in_box(B, lo, hi)
    if not len(rows):
        return _NONE_INSIDE
    B = np.ascontiguousarray(B[rows])
    inside = igl.fast_winding_number(P, F, B) > 0.5
    sq, fi, C = igl.point_mesh_squared_distance(B, P, F)
    dist = np.sqrt(sq)
    bad = inside & (dist > depth)
    return B[bad], C[bad], fi[bad], dist[bad], rows[bad]


def _with_bone_vertices(
    P: FloatArray,
    F: IntArray,
    placed: Sequence[Placed],
    margin: float,
    slack: float,
    hit: IntArray,
    target: FloatArray,
    gap: FloatArray,
    found: list[Inside] | None = None,
) -> tuple[IntArray, FloatArray, FloatArray]:
    """`_violations` plus the pushes that take obstacle vertices out of the muscle.

    An obstacle vertex inside the muscle (``found``, per obstacle; None: every
    obstacle vertex, by `_bone_vertices_in_muscle`) more than the margin plus a
    tenth of a mean edge deep moves the nearest muscle triangle past it: its
    vertices by the least displacement (barycentric weights) that carries the
    nearest point to the margin beyond the obstacle vertex.
    """
    n = len(P)
    push = np.zeros((n, 3))
    size = np.zeros(n)
    # bone vertices deeper than the margin plus a part of a mean edge: the shallow ones
    # sit between the muscle's vertices on the bone (chords of its curved surface)
    depth = margin + defaults.contact_bone_depth * slack / tol.contact
    for b, pl in enumerate(placed):
        if found is None:
            B, C, fi, dist, _ = _bone_vertices_in_muscle(P, F, pl, depth)
        elif pl.allowance is not None:
            continue  # a kept rest overlap: the bone may stand in the muscle as it did
        else:
            deep = found[b].depth > depth
            B, C, fi, dist = (
                found[b].B[deep], found[b].C[deep], found[b].face[deep], found[b].depth[deep]
            )  # fmt: skip
        if not len(B):
            continue
        # into the muscle from the bone vertex: the nearest surface point goes past it
        u = (B - C) / np.maximum(dist, 1e-300)[:, None]
        d = dist + margin + slack
        longest_pushes(push, size, F[fi].ravel(), triangle_pushes(C, P[F[fi]], d[:, None] * u))
    extra = np.flatnonzero(size > slack)
    if not len(extra):
        return hit, target, gap
    # merged with the vertex pushes: the longer displacement wins
    T = np.full((n, 3), np.nan)
    G = np.full(n, np.inf)
    T[hit], G[hit] = target, gap
    longer = np.isnan(T[extra, 0]) | (size[extra] > np.linalg.norm(T[extra] - P[extra], axis=1))
    e = extra[longer]
    T[e] = P[e] + push[e]
    G[e] = np.minimum(G[e], -size[e])
    hit = np.flatnonzero(~np.isnan(T[:, 0]))
    return hit, T[hit], G[hit]


def push_out(
    V: FloatArray,
    F: IntArray,
    placed: Sequence[Placed],
    *,
    volume_target: float,
    margin: float = 0.0,
    A: sp.csr_matrix | None = None,
    max_rounds: int = defaults.contact_rounds,
    bone_vertices: bool | str = False,
    edge: float | None = None,
    near: Near | None = None,
    faces: tuple[IntArray, IntArray] | None = None,
    sides: SideReference | None = None,
    inside: list[Inside] | None = None,
) -> tuple[FloatArray, ContactReport]:
    """Move a muscle's vertices out of obstacles, keeping its volume exact.

    Each round finds the vertices closer than ``margin`` to an obstacle (exact
    closest points, `Obstacle.query`), moves them onto the obstacle's surface
    at the margin along the shortest way out, spreads that displacement
    smoothly over the surrounding rings of the mesh (harmonic, by Jacobi
    sweeps, zero beyond a radius that grows with the depth), and restores the
    volume exactly along the vertex normals masked to zero on every vertex held so
    far (the volume along a line is a cubic: its root). Vertices moved onto an
    obstacle stay there; vertices the volume correction brings too near join
    them in the next round.

    Parameters
    ----------
    V : (n, 3) float64 array
        Positions of the muscle's vertices (closed, outward oriented mesh).
    F : (k, 3) int array
        Triangles.
    placed : sequence of Placed
        The obstacles in this pose.
    volume_target : float
        The volume the result must have.
    margin : float, optional
        Smallest distance a vertex must keep from every obstacle (mesh units).
    A : scipy.sparse.csr_matrix, optional
        The mesh's `musclewrap.mesh.vertex_adjacency` (built here when not given).
    max_rounds : int, optional
        Most push-out rounds.
    bone_vertices : bool or "near", optional
        Also take the obstacles' own vertices out of the muscle (a bone ridge or
        a bone's edge inside the muscle between its vertices): each one inside
        pushes the muscle triangle nearest to it past it. True: every obstacle
        vertex, by the generalized winding number of the whole muscle (robust,
        not cheap: for the rest overlap at preparation); ``"near"``: those
        within a mean edge of muscle vertices in contact, by the muscle's
        surface around them (per pose).
    edge : float, optional
        The mesh's mean edge length (computed when not given).
    near : Near, optional
        Lower bounds of the distances taken earlier (built here when not given):
        only vertices that can come within reach are queried.
    faces : (indptr, indices), optional
        The mesh's `vertex_faces` (``bone_vertices="near"``; built here when not
        given).
    sides : SideReference, optional
        An earlier state of the muscle on its path: a vertex that has come
        through an obstacle since goes back out on the side where it entered,
        not the nearest (`musclewrap.contact.on_their_side`).
    inside : list of Inside, optional
        The obstacles' vertices inside the muscle at ``V`` where the caller has
        looked already (``bone_vertices="near"``, with the same ``near``, margin
        and edge): not looked for again before the first round.

    Returns
    -------
    V : (n, 3) float64 array
        New positions (``V`` itself when nothing was near an obstacle).
    ContactReport
    """
    if edge is None:
        edge = mean_edge_length(V, F)
    slack = tol.contact * edge
    if near is None:
        near = Near(V, placed, margin)
    if A is None:
        A = vertex_adjacency(F, len(V))
    # the volume is corrected along the normals at the start (any direction is exact: the
    # volume along it is a cubic; these stay smooth); the ridge test takes them too
    Z = vertex_normals(V, F)

    def violations(
        P: FloatArray, bones: bool
    ) -> tuple[IntArray, FloatArray, FloatArray, list[float]]:
        hit, target, gap, depths = _violations(P, placed, slack, near, sides)
        if bones:
            hit, target, gap = _with_bone_vertices(P, F, placed, margin, slack, hit, target, gap)
        return hit, target, gap, depths

    hit, target, gap, depths = violations(V, bone_vertices is True)
    depth_before = max(depths, default=0.0)
    found: list[Inside] | None = None  # the bone vertices inside, on the positions of now
    if bone_vertices == "near":
        # Per pose, the bone's vertices inside the surface (a ridge between the muscle's
        # vertices), exact: once the muscle's vertices are out, then on the result
        VF = vertex_faces(F, len(V)) if faces is None else faces
        AA = (A.indptr.astype(np.int64), A.indices.astype(np.int64))
        deep = margin + defaults.contact_bone_depth * edge

        def bones_inside(P: FloatArray) -> list[Inside]:
            return bone_vertices_inside(
                P, F, placed, near, edge=edge, adjacency=AA, faces=VF, deep=deep
            )

        if not len(hit):
            found = bones_inside(V) if inside is None else inside
            hit, target, gap = _with_bone_vertices(
                V, F, placed, margin, slack, hit, target, gap, found
            )
    if not len(hit):
        touching, inside, depth = _final(V, placed, slack, near)
        return V, ContactReport(
            contact_vertices=touching,
            depth_before=depth_before,
            depth_after=depth,
            inside=inside,
            **({} if bone_vertices != "near" else _bone_fields(found)),
        )
    n = len(V)
    P = V.copy()
    held = np.zeros(n, dtype=bool)
    passes = 0
    bones_left: list[Inside] | None = None
    ok = True
    # the first rounds relax every push with its neighbours; the last ones project exactly
    relax_rounds = min(defaults.contact_relax_rounds, max_rounds - 1)
    if bone_vertices is True:  # once per muscle: relax longer, fewer folds
        relax_rounds = max(relax_rounds, max_rounds // 2)
    relax_from, relax_until = 1, relax_rounds  # the rounds of this pass that relax
    budget = max_rounds
    rounds = 0
    while rounds < budget:
        rounds += 1
        # a pose's shallow pushes (what the cage's steps left) relax in a pass's first
        # round only, then land exactly: relaxed again they land short again and take
        # another round each; at rest (every bone vertex) every round of the pass relaxes
        shallow = bone_vertices is not True and bool(
            np.linalg.norm(target - P[hit], axis=1).max() <= defaults.contact_relax_depth * edge
        )
        relax = relax_from <= rounds <= (min(relax_from, relax_until) if shallow else relax_until)
        radius = _push(P, A, hit, target, edge, held, relax=relax)
        held[hit] = True
        t, Zm = _volume_away_from(P, F, A, Z, held, radius, volume_target)
        if not np.isfinite(t):
            ok = False
            break
        P += t * Zm
        hit, target, gap, depths = violations(P, bone_vertices is True)
        found = None
        if not len(hit) and bone_vertices == "near" and passes < 3:
            # the muscle's vertices are out: the bone's, looked at on this surface
            passes += 1
            found = bones_inside(P)
            hit, target, gap = _with_bone_vertices(
                P, F, placed, margin, slack, hit, target, gap, found
            )
            if len(hit):
                # the bone's pushes relaxed with their neighbours as the first ones were,
                # with rounds of their own; and looked at again after them
                bones_left = found
                found = None
                relax_from, relax_until = rounds + 1, rounds + relax_rounds
                budget = max(budget, rounds + relax_rounds + 3)
        if not len(hit):
            break
    reason = ""
    if len(hit):
        ok = False
        reason = _unmet(rounds, len(hit), placed, depths, bones_left)
    P, rel = _volume_restored(P, F, volume_target)
    if rel > tol.volume:
        ok = False
        reason = (reason + "; " if reason else "") + f"volume error {rel:.3g} after contact"
    touching, inside, depth = _final(P, placed, slack, near)
    report = ContactReport(
        contact_vertices=touching,
        inside=inside,
        depth_before=depth_before,
        depth_after=depth,
        moved_max=float(np.linalg.norm(P - V, axis=1).max()),
        rounds=rounds,
        ok=ok,
        reason=reason,
        **({} if bone_vertices != "near" else _bone_fields(found or bones_inside(P))),
    )
    return P, report


def _push(
    P: FloatArray,
    A: sp.csr_matrix,
    hit: IntArray,
    target: FloatArray,
    edge: float,
    held: npt.NDArray[np.bool_],
    *,
    relax: bool,
) -> int:
    """One round's push of the vertices ``hit`` to ``target``, spread over their rings.

    In place on ``P``; returns the spread's radius in rings. The harmonic spread is zero
    beyond it. ``relax``: the pushed vertices are relaxed with their neighbours too
    (neighbours projected onto different sheets of a concave bone, or along converging
    normals, would cross; what the relaxation leaves inside is pushed again in the next
    round); else they land on their targets exactly.
    """
    Dall, level, radius = _spread(A, hit, target - P[hit], edge, held)
    if relax:
        moving = np.flatnonzero(level <= radius)
        _smooth(A.indptr, A.indices, Dall, moving, defaults.contact_relax, 0.5)
        P += Dall
    else:
        P += Dall
        P[hit] = target
    return int(radius)


def _volume_away_from(
    P: FloatArray,
    F: IntArray,
    A: sp.csr_matrix,
    Z: FloatArray,
    held: npt.NDArray[np.bool_],
    radius: int,
    volume_target: float,
) -> tuple[float, FloatArray]:
    """The exact volume's step along the normals ``Z``, ramped to zero at the held vertices.

    Returns ``t`` (NaN where the cubic has no finite root) and the ramped direction:
    ``P + t * Zm`` has the target volume.
    """
    ramp = min(radius + 2, 12)
    level = rings(A, np.flatnonzero(held), ramp)
    mask = np.clip(level / (ramp + 1.0), 0.0, 1.0)
    Zm = Z * mask[:, None]
    return _volume_step(P, F, Zm, volume_target), Zm


def _unmet(
    rounds: int,
    within: int,
    placed: Sequence[Placed],
    depths: list[float],
    bones_left: list[Inside] | None,
) -> str:
    """Why the contact is not met: the deepest remaining violation per obstacle."""
    names = {}
    for pl, d in zip(placed, depths, strict=True):
        if d > 0:
            names[pl.name] = d
    if not names and bones_left is not None:
        for pl, f in zip(placed, bones_left, strict=True):
            if f.deepest > 0:
                names[pl.name] = -f.deepest
    return (
        f"contact not met after {rounds} rounds: {within} vertices within the margin, "
        + ", ".join(
            f"{k} {v:.3g} deep" if v > 0 else f"{k} {-v:.3g} deep inside the muscle"
            for k, v in names.items()
        )
    ).rstrip(", ")


def _volume_restored(P: FloatArray, F: IntArray, volume_target: float) -> tuple[FloatArray, float]:
    """``P`` with its volume restored over the whole surface where it is off; its error.

    Where the rounds left no volume to take away from the held vertices, the volume
    is restored along every vertex's normal (the contact stays unmet, and is reported).
    """
    rel = abs(volume(P, F) - volume_target) / abs(volume_target)
    if rel > tol.volume:
        Z = vertex_normals(P, F)
        t = _volume_step(P, F, Z, volume_target)
        if np.isfinite(t):
            P = P + t * Z
        rel = abs(volume(P, F) - volume_target) / abs(volume_target)
    return P, rel


def nudge(
    V: FloatArray,
    F: IntArray,
    A: sp.csr_matrix,
    hit: IntArray,
    D: FloatArray,
    *,
    volume_target: float,
    edge: float,
) -> FloatArray | None:
    """The fine vertices ``hit`` moved by ``D``, smoothly over the rings round them, volume exact.

    What the cage cannot do for a few vertices a fraction of an edge inside another
    muscle (the last of `musclewrap.solver.meet`'s rounds): the pushes spread
    harmonically over the rings of the mesh round them (zero beyond a radius that
    grows with the longest push, as `push_out` spreads its own), then the volume
    restored exactly along the vertex normals of the rest of the surface (zero over the
    pushes' rings). None where the volume cannot be restored.
    """
    Dall, level, radius = _spread(A, hit, D, edge, beyond=2)
    P = V + Dall
    # away from the pushes, over the whole surface beyond their rings (a ramp round them
    # would press the neighbouring rings into what was pushed away from)
    Zm = vertex_normals(P, F) * np.clip((level - radius) / 2.0, 0.0, 1.0)[:, None]
    t = _volume_step(P, F, Zm, volume_target)
    if not np.isfinite(t):
        return None
    return P + t * Zm


def press(
    V: FloatArray,
    F: IntArray,
    A: sp.csr_matrix,
    corners: IntArray,
    weights: FloatArray,
    ways: FloatArray,
    amounts: FloatArray,
    *,
    volume_target: float,
    edge: float,
    shape_rest: FloatArray | None = None,
    umbrella: sp.csr_matrix | None = None,
) -> FloatArray | None:
    """The fine vertices moved as a thin plate that meets one-sided pushes, volume exact.

    Each push ``c`` asks the point ``sum_j weights[c, j] V[corners[c, j]]`` to move by
    at least ``amounts[c]`` along the unit ``ways[c]`` (a vertex: one corner of weight
    1; a point of a triangle: its barycentric weights). The displacement ``D`` is the
    one that changes the uniform Laplacian least (``sum |(U D)_i|^2``, what the shape
    change measures) over the rings within a radius of the pushed vertices
    (``defaults.muscle_plate_spread`` mean edges per edge pushed, at most 12 rings),
    zero beyond, subject to every push, one-sided (`_plate`'s Newton steps: a push that
    the others already carry past its amount asks nothing). Unlike `nudge`'s harmonic spread a
    push leaves no cone, and the pushes need not agree with each other. Then the
    volume is restored exactly along the vertex normals beyond the rings. None where
    nothing moves or the volume cannot be restored. ``umbrella``: the mesh's uniform
    Laplacian (`musclewrap.mesh.umbrella_laplacian`, made here when None);
    ``shape_rest``: its vectors' lengths at rest (`PreparedMuscle.umbrella_rest_lengths`).
    """
    n = len(V)
    U = umbrella_laplacian(F, n) if umbrella is None else umbrella
    on = weights > 0.0
    if defaults.muscle_plate_drop and on.any():
        # pushes that disagree, on one vertex or on neighbours, are left out (the cage's)
        acc, mag = np.zeros((n, 3)), np.zeros(n)
        wa = weights * amounts[:, None]
        np.add.at(acc, corners[on], (wa[:, :, None] * ways[:, None, :])[on])
        np.add.at(mag, corners[on], wa[on])
        pushed = mag > 0.0
        bad = pushed & (np.linalg.norm(acc, axis=1) < 0.5 * mag)
        src = np.repeat(np.arange(n), np.diff(A.indptr))
        e = pushed[src] & pushed[A.indices]
        opp = np.einsum("ij,ij->i", acc[src[e]], acc[A.indices[e]]) < 0.0
        bad[src[e][opp]] = True
        keep = ~(bad[corners] & on).any(axis=1)
        corners, weights, ways, amounts = corners[keep], weights[keep], ways[keep], amounts[keep]
        on = on[keep]
    hit = np.unique(corners[on])
    if not len(hit) or not (amounts > 0.0).any():
        return None
    depth = float(amounts.max())
    radius = int(min(np.ceil(defaults.muscle_plate_spread * depth / edge) + 1, 12))
    level = rings(A, hit, radius + 2)
    R = np.flatnonzero(level <= radius)
    m = len(R)
    local = np.full(n, -1, dtype=np.int64)
    local[R] = np.arange(m)
    Us = U[np.flatnonzero(level <= radius + 1)][:, R].tocsr()
    k = len(amounts)
    # the pushes' rows over the unknowns (each region vertex's x, y and z in turn)
    rr = np.repeat(np.arange(k), 9)
    cc = (3 * local[corners][:, :, None] + np.arange(3)[None, None, :]).reshape(k, 9)
    vv = (weights[:, :, None] * ways[:, None, :]).reshape(k, 9)
    keep = vv.ravel() != 0.0
    C = sp.csr_matrix((vv.ravel()[keep], (rr[keep], cc.ravel()[keep])), shape=(k, 3 * m))
    D = _plate(Us, C, amounts, defaults.muscle_plate_weight, edge)
    if not np.isfinite(D).all() or np.abs(D).max() > 1.5 * depth:
        return None
    Dall = np.zeros((n, 3))
    Dall[R] = D.reshape(m, 3)
    P = V + Dall
    # pushes that disagree (a thin wall pressed from both sides) bend the plate: left to the cage
    _, rise = _lengths_raised(U, np.flatnonzero(level <= radius + 1), V, P)
    if rise.max() > defaults.muscle_plate_rise * edge:
        return None
    Zm = vertex_normals(P, F) * np.clip((level - radius) / 2.0, 0.0, 1.0)[:, None]
    t = _volume_step(P, F, Zm, volume_target)
    if not np.isfinite(t):
        return None
    P = P + t * Zm
    if shape_rest is not None:
        # the shape change where the step raised it, the volume's ramp round the plate too
        near = np.flatnonzero(level <= radius + 3)
        after, rise = _lengths_raised(U, near, V, P)
        over = np.abs(after - shape_rest[near]) > defaults.muscle_plate_shape * edge
        if (over & (rise > 0.0)).any():
            return None
    return P


def _plate(Us: sp.csr_matrix, C: sp.csr_matrix, a: FloatArray, w: float, edge: float) -> FloatArray:
    """The least ``|Us D|^2 / 2 + w/2 sum max(0, a - C D)^2``: one-sided pushes on a plate.

    ``D`` holds the region's displacements, each vertex's x, y and z in turn,
    ``Us`` the uniform Laplacian's rows over the region and the ring round it (zero
    beyond). The objective is convex and piecewise quadratic: on the pushes left short
    (``C D < a``) its least solves ``(I3 (x) Us^T Us + w Ca^T Ca) D = w Ca^T a``. Each
    Newton step takes that system's solution, to ``defaults.muscle_plate_iterations``
    conjugate-gradient iterations from the last ``D`` (Jacobi-preconditioned), as a
    direction, and goes along it as far as the objective falls (halving from the whole
    step: the plain active-set iteration, every step taken whole, cycles where the pushes
    interact, a bi-Laplacian being no M-matrix). The iterations are compiled
    (`_plate_cg_kernel`: scipy's `cg` on a `LinearOperator` spent more on its calls than on
    the products, 14.6 of a muscle-frame's 46 ms of contact on the LHDL walk, BENCHMARKS.md). It stops where a step keeps its set and
    is taken whole, where it moves no unknown by more than ``defaults.muscle_plate_still``
    mean edges, or after ``defaults.muscle_plate_sets`` steps. Matrix-free: a sparse
    factorisation of the coupled plate cost 0.02-0.7 s a step on the 18 muscles' regions
    of 900-6,500 vertices; the 47 plates of one of their frames take 1.4 s so against
    21 s (BENCHMARKS.md, "The plate's cost and its steps").
    """
    m = Us.shape[1]
    n = 3 * m
    UsT = Us.T.tocsr()
    CT = C.T.tocsr()
    base = np.repeat(np.asarray(Us.multiply(Us).sum(axis=0)).ravel(), 3) + 1e-9
    C2 = C.multiply(C).tocsr()
    # the CSR arrays of the conjugate gradients' products, as the kernel takes them
    csr = [
        np.ascontiguousarray(arr, dtype=dt)
        for M in (Us, UsT, C, CT)
        for arr, dt in ((M.indptr, np.int64), (M.indices, np.int64), (M.data, np.float64))
    ]

    def bend(D: FloatArray) -> FloatArray:
        return (UsT @ (Us @ D.reshape(m, 3))).ravel() + 1e-9 * D

    def f(D: FloatArray) -> float:
        short = np.maximum(a - C @ D, 0.0)
        return 0.5 * float(D @ bend(D)) + 0.5 * w * float(short @ short)

    D = np.zeros(n)
    active = a > 0.0
    value = f(D)
    still = defaults.muscle_plate_still * edge
    for _ in range(defaults.muscle_plate_sets):
        on = active.astype(np.float64)
        jacobi = 1.0 / (base + w * (C2.T @ on))
        target = _plate_cg_kernel(
            *csr, on, float(w), w * (CT @ (on * a)), D, jacobi,
            defaults.muscle_plate_iterations, 1e-12,
        )  # fmt: skip
        step = target - D
        slope = float(step @ bend(D) - w * (np.maximum(a - C @ D, 0.0) @ (C @ step)))
        t = 1.0
        while t > 1e-3 and f(D + t * step) > value + 1e-4 * t * slope:
            t *= 0.5
        D = D + t * step
        value = f(D)
        # a push the others carry past its amount asks nothing; one left short is taken on
        again = (C @ D) < a
        if t * np.abs(step).max() <= still or (t == 1.0 and (again == active).all()):
            break
        active = again
    return D


def _lengths_raised(
    U: sp.csr_matrix, rows: IntArray, V: FloatArray, P: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The lengths of ``U``'s vectors at ``P`` on ``rows``, and how much longer than at ``V``."""
    after = np.linalg.norm(U[rows] @ P, axis=1)
    return after, after - np.linalg.norm(U[rows] @ V, axis=1)


def _bone_fields(found: list[Inside]) -> dict[str, float]:
    """The report's count and depth of obstacle vertices inside the muscle."""
    return {
        "bone_inside": sum(len(f.rows) for f in found),
        "bone_inside_depth": max((f.deepest for f in found), default=0.0),
    }


def _final(
    P: FloatArray, placed: Sequence[Placed], slack: float, near: Near
) -> tuple[int, int, float]:
    """Vertices in contact (within twice the slack of the margin), inside an obstacle, deepest.

    Exact: every vertex that can be that near (``near``'s bounds) takes the
    closest-point query.
    """
    n = len(P)
    touching = np.zeros(n, dtype=bool)
    inside = np.zeros(n, dtype=bool)
    depth = 0.0
    for b, pl in enumerate(placed):
        allowed = near.allowed[b]
        # nearer than the margin + slack, or inside (a kept overlap allows a vertex inside)
        reach = np.maximum(allowed + 2.0 * slack, 0.0)
        r = near.within(b, P, reach - allowed)
        if not len(r):
            continue
        lower = np.empty(len(r))
        idx, phi, _, _ = pl.obstacle.query(pl.to_obstacle(P[r]), reach[r], lower)
        near.learn(b, r, P[r], lower)
        idx = r[idx]
        touching[idx[phi < allowed[idx] + 2.0 * slack]] = True
        inside[idx[phi < 0]] = True
        depth = max(depth, float(-phi.min(initial=0.0)))
    return int(touching.sum()), int(inside.sum()), depth

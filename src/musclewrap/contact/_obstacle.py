"""A rigid closed surface (a bone) as an obstacle: signed distance, closest points, depth."""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from ..mesh import MeshError, check_mesh, half_edges, repair_mesh, tidy_mesh

__all__ = ["Obstacle", "bone_surface"]

#: version of the stored grid; part of the cache key
_FORMAT = 3  # 2: a band of at least four cells; 3: no coarser than the node budget


def bone_surface(
    V: FloatArray, F: IntArray, *, source: str = "bone", close: bool = False
) -> tuple[FloatArray, IntArray, list[str]]:
    """A bone mesh as contact needs it: duplicates merged, outward, and closed.

    Contact needs the bone's inside. An open bone is closed with PyMeshFix
    (``close``, as a muscle is repaired) or refused.

    Parameters
    ----------
    V : (n, 3) float64 array
    F : (m, 3) int array
    source : str, optional
        File name quoted in messages.
    close : bool, optional
        Close an open bone instead of refusing it.

    Returns
    -------
    V, F : arrays
    notes : list of str
        What was changed.

    Raises
    ------
    musclewrap.mesh.MeshError
        If the bone is open and ``close`` is off, or it cannot be closed.
    """
    V, F, notes = tidy_mesh(V, F)
    check = check_mesh(V, F)
    if check.volume < 0:
        F = F[:, ::-1].copy()
        notes.append("faces were oriented inward: flipped")
    if check.boundary_edges or not len(F):
        if not close:
            raise MeshError(
                f"{source}: the bone is not closed ({check.boundary_edges} boundary edges): "
                "its inside is not defined; close it first (e.g. PyMeshFix)"
            )
        V, F, repaired = repair_mesh(V, F, source=source)
        notes += [f"open ({check.boundary_edges} boundary edges): closed for contact", *repaired]
    return V, F, notes


def pseudo_normals(V: FloatArray, F: IntArray) -> tuple[FloatArray, ...]:
    """Face normals, angle-weighted vertex normals and edge normals of a surface.

    Returns ``FN (m, 3)``, ``VN (n, 3)``, ``EN (e, 3)`` (the sum of an edge's two
    face normals) and ``FE (m, 3)``: per face, the row of ``EN`` of its edge
    ``e`` (joining corners ``e`` and ``e + 1``). What `signed_from_closest` takes.
    """
    import igl

    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    FN = np.ascontiguousarray(igl.per_face_normals(V, F, np.array([0.0, 0.0, 1.0])))
    VN = np.ascontiguousarray(
        igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_ANGLE)
    )
    E = np.sort(F[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    key = E[:, 0] * len(V) + E[:, 1]
    uniq, inv = np.unique(key, return_inverse=True)
    FN3 = np.repeat(FN, 3, axis=0)
    EN = np.stack([np.bincount(inv, FN3[:, i], minlength=len(uniq)) for i in range(3)], 1)
    FE = np.ascontiguousarray(inv.reshape(-1, 3), dtype=np.int64)
    return FN, VN, np.ascontiguousarray(EN), FE


def signed_from_closest(
    P: FloatArray,
    C: FloatArray,
    face: IntArray,
    sq: FloatArray,
    V: FloatArray,
    F: IntArray,
    normals: tuple[FloatArray, ...],
) -> tuple[FloatArray, FloatArray]:
    """Signed distance and outward direction from closest points on a closed surface.

    ``C``, ``face`` and ``sq`` are a closest-point query's answer for the points
    ``P`` (libigl's); the side is the angle-weighted pseudo-normal's at ``C`` (on
    a face, an edge or a vertex: Baerentzen & Aanaes 2005); ``normals`` from
    `pseudo_normals`. Returns ``phi (k,)`` (< 0 inside) and ``N (k, 3)``.
    """
    P = np.ascontiguousarray(P, dtype=np.float64)
    phi = np.empty(len(P))
    N = np.empty((len(P), 3))
    _signed_kernel(
        P,
        np.ascontiguousarray(C, dtype=np.float64),
        np.ascontiguousarray(face, dtype=np.int64).ravel(),
        np.ascontiguousarray(sq, dtype=np.float64).ravel(),
        np.ascontiguousarray(V, dtype=np.float64),
        np.ascontiguousarray(F, dtype=np.int64),
        *normals,
        phi,
        N,
    )
    return phi, N


class Obstacle:
    """Signed distance, closest points and inside test against one closed bone surface.

    Built once per bone (in the bone's own frame, or read back with `cached`);
    `query` and `measure` are called per pose with the muscle's vertices
    expressed in that frame. `query` gives the exact signed distance, closest
    point and outward direction of every point that comes within a given
    reach of the surface (the contact solve, `musclewrap.contact.push_out`).
    `measure`'s answer is exact: the count of points inside and the largest
    distance to the surface among them, as a closest-point query with the
    angle-weighted pseudo-normal sign (Baerentzen & Aanaes 2005) on every
    point would give; the grid only decides which points need that query.

    Parameters
    ----------
    V : (n, 3) float64 array
        Bone vertices.
    F : (m, 3) int array
        Bone triangles, outward oriented.
    max_grid_nodes : int, optional
        Size of the signed-distance grid over the bone's bounding box.

    Notes
    -----
    A grid over the bone's bounding box, of the finest spacing ``h`` that
    ``max_grid_nodes`` allows (whatever the size of its triangles), holds, for each node,
    an interval for the signed distance: exact (both ends equal) near the
    surface (the "band": nodes within ``k`` cells of a cell holding a bone
    vertex, ``k`` at least 4) and inside; ``[far, inf)`` outside off the band, where ``far > 0``
    follows from ``k`` and the longest edge (every point of a triangle is
    within longest-edge/sqrt(3) of a vertex). The side of the regions off the
    band comes from generalized winding numbers (Jacobson et al. 2013),
    robust to small holes. Intervals are stored as float32, rounded outward.

    The signed distance is 1-Lipschitz, so at a point ``p`` it lies within
    each of its cell's eight corner intervals widened by ``|p - corner|``;
    their intersection decides the side of nearly every point. Only points
    whose interval contains 0 (a thin shell at the surface) take the exact
    closest-point query, and of the points inside, the exact depth is taken
    in order of their upper bound until no remaining bound can beat the
    deepest found. Points outside the bounding box are outside.
    """

    def __init__(
        self,
        V: FloatArray,
        F: IntArray,
        *,
        max_grid_nodes: int = 500_000,
        _grid: dict[str, np.ndarray] | None = None,
    ) -> None:
        import igl

        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        self._tree = igl.AABB()
        self._tree.init(self.V, self.F)
        self._normals = pseudo_normals(self.V, self.F)
        grid = _grid if _grid is not None else self._build(max_grid_nodes)
        self.lo = np.asarray(grid["lo"], dtype=np.float64)
        self.h = float(grid["h"])
        self._shape = np.asarray(grid["shape"], dtype=np.int64)
        self._grid = grid
        self._lo_sd = grid["lo_sd"]
        self._hi_sd = grid["hi_sd"]
        self.hi = self.lo + self.h * (self._shape - 1)
        self._strides = np.array([self._shape[1] * self._shape[2], self._shape[2], 1])
        corners = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, 8).T
        self._corner_offsets = corners @ self._strides

    # ------------------------------------------------------------------ build
    def _build(self, max_grid_nodes: int) -> dict[str, np.ndarray]:
        import igl
        from scipy import ndimage

        V, F = self.V, self.F
        lo, hi = V.min(axis=0), V.max(axis=0)
        ext = hi - lo
        L = np.linalg.norm(V[F[:, [1, 2, 0]]] - V[F], axis=2)
        # the finest spacing the node budget allows, whatever the triangles' size: the
        # contact's conditions take the grid's trilinear distance, and over a model's
        # coarse bone (gait2392's pelvis: edges of 22 mm) a spacing of half an edge put
        # it 2.6 mm off the exact one; a flat or thin box keeps 400 cells along its longest
        # side at most
        h = float(max((np.prod(ext) / max_grid_nodes) ** (1 / 3), ext.max() / 400.0, 1e-9))
        # every point of a triangle is within (longest edge)/sqrt(3) of one of its vertices
        slack = float(L.max() / np.sqrt(3.0))
        reach = h * np.sqrt(3.0) / 2.0
        k = int(np.ceil((slack + reach) / h - 0.5 + 1e-3))
        # exact values at least four cells out: the bounds are tight where contact looks
        # (a muscle's vertices near a bone, and where they were on the way: SideReference)
        k = max(k, int(np.ceil(3.5 + slack / h)))
        far = (k + 0.5) * h - slack  # non-band nodes are at least this far from the surface
        shape = np.ceil(ext / h).astype(np.int64) + 1
        occupied = np.zeros(tuple(shape), dtype=bool)
        iv = np.rint((V - lo) / h).astype(np.int64)
        occupied[iv[:, 0], iv[:, 1], iv[:, 2]] = True
        band = ndimage.binary_dilation(occupied, np.ones((3, 3, 3), bool), iterations=k)
        lo_sd = np.empty(tuple(shape), dtype=np.float64)
        hi_sd = np.empty(tuple(shape), dtype=np.float64)

        def nodes(ii: tuple[IntArray, ...]) -> FloatArray:
            return lo + h * np.stack(ii, axis=1).astype(np.float64)

        # off the band: the side of each connected region from winding numbers at up to 32
        # of its nodes; where they disagree (the region leaks through a hole) at every node
        labels, _ = ndimage.label(~band)
        regions = [
            tuple(a + s.start for a, s in zip(np.nonzero(labels[sl] == i), sl, strict=True))
            for i, sl in enumerate(ndimage.find_objects(labels), start=1)
        ]
        rng = np.random.default_rng(0)
        picks = [rng.choice(len(ii[0]), size=min(32, len(ii[0])), replace=False) for ii in regions]
        Gp = [nodes(tuple(a[p] for a in ii)) for ii, p in zip(regions, picks, strict=True)]
        wp = igl.fast_winding_number(V, F, np.vstack(Gp)) > 0.5 if Gp else np.zeros(0, bool)
        inside = np.zeros(tuple(shape), dtype=bool)
        leaky, o = [], 0
        for ii, p in zip(regions, picks, strict=True):
            w = wp[o : o + len(p)]
            o += len(p)
            if w.all() == w.any():
                inside[ii] = bool(w[0])
            else:
                leaky.append(ii)
        if leaky:
            jj = tuple(np.concatenate(a) for a in zip(*leaky, strict=True))
            inside[jj] = igl.fast_winding_number(V, F, nodes(jj)) > 0.5
        # inside and on the band: exact signed distance (pseudo-normal sign, as for the
        # query points); outside off the band: at least `far`
        exact = band | inside
        ii = np.nonzero(exact)
        G = np.ascontiguousarray(nodes(ii))
        lo_sd[ii] = hi_sd[ii] = self._signed(G)[0]
        lo_sd[~exact], hi_sd[~exact] = far, np.inf
        return {
            "lo": lo,
            "h": np.float64(h),
            "shape": shape,
            "lo_sd": _round(lo_sd, -1).ravel(),
            "hi_sd": _round(hi_sd, +1).ravel(),
        }

    # ------------------------------------------------------------------ cache
    @staticmethod
    def cache_name(V: FloatArray, F: IntArray) -> str:
        """File name of the bone's grid in a cache folder (a hash of its content)."""
        from .._hashing import cache_key

        V = np.ascontiguousarray(V, dtype=np.float64)
        F = np.ascontiguousarray(F, dtype=np.int64)
        return f"bone-probe-{cache_key(V, F, str(_FORMAT))[:32]}.npz"

    @classmethod
    def cached(
        cls, V: FloatArray, F: IntArray, cache_dir: Path | None, *, name: str | None = None
    ) -> Obstacle:
        """Build, or read back from ``cache_dir`` (keyed by the bone's content).

        ``name``: the `cache_name` of ``V, F`` where the caller has it already.
        """
        from .._cache import cached_arrays

        V = np.ascontiguousarray(V, dtype=np.float64)
        F = np.ascontiguousarray(F, dtype=np.int64)
        path = None if cache_dir is None else Path(cache_dir) / (name or cls.cache_name(V, F))
        built: list[Obstacle] = []

        def build() -> dict[str, np.ndarray]:
            built.append(cls(V, F))
            return built[0]._grid

        grid = cached_arrays(path, build)
        return built[0] if built else cls(V, F, _grid=grid)

    # ------------------------------------------------------------------ exact
    def signed(self, P: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Exact signed distance (< 0 inside), closest point and outward direction.

        The side is the angle-weighted pseudo-normal's at the closest point (on a
        face, an edge or a vertex: Baerentzen & Aanaes 2005).

        Parameters
        ----------
        P : (k, 3) float64 array
            Points in the obstacle's frame.

        Returns
        -------
        phi : (k,) float64 array
        C : (k, 3) float64 array
            Closest points on the surface.
        N : (k, 3) float64 array
            Unit outward directions (see `query`).
        """
        P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
        if not len(P):
            return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
        sq, face, C = self._tree.squared_distance(self.V, self.F, P)
        phi, N = signed_from_closest(P, C, face, sq, self.V, self.F, self._normals)
        return phi, C, N

    _signed = signed

    def first_entry(
        self, A: FloatArray, B: FloatArray, *, tol: float = 1e-3
    ) -> tuple[npt.NDArray[np.bool_], FloatArray, FloatArray]:
        """Where each straight way ``A -> B`` first enters the obstacle (continuous test).

        Sphere tracing on the grid's lower bounds of the signed distance (which
        cannot step over the surface: the distance is 1-Lipschitz), the exact
        signed distance wherever a bound allows the inside, then bisection on the
        exact side down to ``tol`` of the bone's grid spacing. A way that starts
        inside enters at its start's closest point. Steps are at least a quarter
        of the grid's spacing: a way that only grazes the surface, in by less
        than that along it (a chord across a ridge that a sliding vertex went
        round), may be taken as not entering.

        Parameters
        ----------
        A, B : (k, 3) float64 arrays
            Starts and ends, in the obstacle's frame.
        tol : float, optional
            Precision of the entry along the way, in grid spacings.

        Returns
        -------
        found : (k,) bool array
            Whether the way enters the obstacle.
        E : (k, 3) float64 array
            Entry points on the surface (where found).
        N : (k, 3) float64 array
            Unit outward directions there (where found).
        """
        A = np.ascontiguousarray(A, dtype=np.float64).reshape(-1, 3)
        B = np.ascontiguousarray(B, dtype=np.float64).reshape(-1, 3)
        k = len(A)
        found = np.zeros(k, dtype=bool)
        E = np.zeros((k, 3))
        N = np.zeros((k, 3))
        if not k:
            return found, E, N
        phi, C, D = self.signed(A)
        start = phi < 0
        found[start], E[start], N[start] = True, C[start], D[start]
        D_ab = B - A
        length = np.maximum(np.linalg.norm(D_ab, axis=1), 1e-300)
        step = 0.25 * self.h  # the smallest step along a way near the surface
        t = np.zeros(k)
        lo_t = np.zeros(k)
        hi_t = np.full(k, np.inf)
        todo = np.flatnonzero(~start)
        samples = np.arange(32)
        for _ in range(400):
            if not len(todo):
                break
            t_in = np.empty(len(todo))
            t_out = np.empty(len(todo))
            _march_kernel(
                A[todo], B[todo], t[todo], self.lo, self.h, self._shape, self._lo_sd,
                self._hi_sd, step, t_in, t_out,
            )  # fmt: skip
            maybe = t_in <= 1.0
            todo, t_in, t_out = todo[maybe], t_in[maybe], t_out[maybe]
            if not len(todo):
                break
            # near the surface the bounds are loose: the side at 32 steps at once, by the
            # bounds where they decide it, else exactly
            T = np.minimum(t_in[:, None] + samples[None, :] * (step / length[todo])[:, None], 1.0)
            P = (A[todo, None, :] + T[:, :, None] * D_ab[todo, None, :]).reshape(-1, 3)
            lower, upper = self.bounds(P)
            phi = np.where(upper < 0, upper, lower)
            unsure = np.flatnonzero((lower <= 0) & (upper >= 0))
            if len(unsure):
                phi[unsure] = self.signed(P[unsure])[0]
            phi = phi.reshape(T.shape)
            inside = phi < 0
            got = inside.any(axis=1)
            j = np.argmax(inside, axis=1)
            rows = np.flatnonzero(got)
            prev = np.where(j[rows] > 0, T[rows, np.maximum(j[rows] - 1, 0)], t_out[rows])
            lo_t[todo[rows]], hi_t[todo[rows]] = prev, T[rows, j[rows]]
            on = np.flatnonzero(~got & (T[:, -1] < 1.0))
            t[todo[on]] = T[on, -1] + np.maximum(phi[on, -1], step) / length[todo[on]]
            todo = todo[on]
        hit = np.flatnonzero(np.isfinite(hi_t))
        if len(hit):
            a, b = lo_t[hit], hi_t[hit]
            rounds = int(
                np.ceil(np.log2(max(float(((b - a) * length[hit]).max()), 1e-300) / (tol * self.h)))
            )
            for _ in range(max(rounds, 0)):
                mid = 0.5 * (a + b)
                inside = self.signed(A[hit] + mid[:, None] * D_ab[hit])[0] < 0
                b = np.where(inside, mid, b)
                a = np.where(inside, a, mid)
            _, C, D = self.signed(A[hit] + a[:, None] * D_ab[hit])
            found[hit], E[hit], N[hit] = True, C, D
        return found, E, N

    @property
    def convexity(self) -> FloatArray:
        """Per vertex, the largest convex normal curvature toward a neighbour (1/length).

        ``-2 n . (w - v) / |w - v|^2`` over the neighbours ``w`` of ``v`` (the
        circle tangent to the surface at ``v`` through ``w``), 0 where no
        neighbour lies below the tangent plane. A ridge of radius ``R`` has
        about ``1 / R``.
        """
        if getattr(self, "_convexity", None) is None:
            k = np.zeros(len(self.V))
            ip, ix = self.adjacency
            _convexity_kernel(self.V, np.ascontiguousarray(self._normals[1]), ip, ix, k)
            self._convexity = k
        return self._convexity

    @property
    def longest_edges(self) -> FloatArray:
        """Per vertex, the length of its longest edge (0 for a vertex of no triangle)."""
        if getattr(self, "_longest_edges", None) is None:
            E = half_edges(self.F)
            L = np.linalg.norm(self.V[E[:, 0]] - self.V[E[:, 1]], axis=1)
            out = np.zeros(len(self.V))
            np.maximum.at(out, E[:, 0], L)
            np.maximum.at(out, E[:, 1], L)
            self._longest_edges = out
        return self._longest_edges

    @property
    def adjacency(self) -> tuple[IntArray, IntArray]:
        """The vertices' neighbours on the surface, CSR ``(indptr, indices)`` (built once)."""
        if getattr(self, "_adjacency", None) is None:
            from ..mesh import vertex_adjacency

            A = vertex_adjacency(self.F, len(self.V))
            self._adjacency = (A.indptr.astype(np.int64), A.indices.astype(np.int64))
        return self._adjacency

    def vertices_near(
        self, Q: FloatArray, radius: float, convexity: float = -np.inf
    ) -> tuple[IntArray, IntArray]:
        """The obstacle's vertices within ``radius`` of a point of ``Q``, and the nearest one.

        Parameters
        ----------
        Q : (k, 3) float64 array
            Points in the obstacle's frame.
        radius : float
        convexity : float, optional
            Only vertices whose `convexity` exceeds this.

        Returns
        -------
        rows : (j,) int64 array
            Vertices (rows of `V`), sorted.
        nearest : (j,) int64 array
            For each, the nearest point of ``Q`` (an index into it).

        Notes
        -----
        The vertices are binned once per ``radius`` in cells of that side; a
        point looks in its cell and the 26 around it (compiled).
        """
        bins = self.__dict__.setdefault("_vertex_cells", {})
        key = (float(radius), float(convexity))
        if key not in bins:
            keep = np.flatnonzero(self.convexity > convexity)
            idx, R, lo, dims, indptr = _bin_points(self.V[keep], radius)
            bins[key] = (keep[idx], R, lo, dims, indptr)
        idx, R, lo, dims, indptr = bins[key]
        Q = np.ascontiguousarray(Q, dtype=np.float64)
        if not len(Q):
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        best = np.full(len(idx), np.inf)
        which = np.full(len(idx), -1, dtype=np.int64)
        _nearest_within_kernel(Q, R, lo, float(radius), dims, indptr, best, which)
        found = np.flatnonzero(which >= 0)
        order = np.argsort(idx[found])
        return idx[found][order], which[found][order]

    # ------------------------------------------------------------------ query
    def bounds(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Lower and upper bounds of the signed distance of each point (< 0 inside).

        From the grid alone (no closest-point query): the signed distance at
        ``p`` lies within every corner interval of its cell widened by
        ``|p - corner|``. Outside the grid's box the lower bound is the
        distance to the box and the upper bound infinite.

        Parameters
        ----------
        Q : (k, 3) float64 array
            Points in the bone's frame.

        Returns
        -------
        lower, upper : (k,) float64 arrays
        """
        P = np.ascontiguousarray(Q, dtype=np.float64)
        lower = np.empty(len(P))
        upper = np.empty(len(P))
        _bounds_kernel(
            P,
            self.lo,
            self.h,
            self._shape,
            self._lo_sd,
            self._hi_sd,
            lower,
            upper,
        )
        return lower, upper

    def interpolate(self, Q: FloatArray, reach: float) -> tuple[IntArray, FloatArray, FloatArray]:
        """Signed distance and its gradient from the grid (trilinear), near the surface.

        Cheap and approximate (the grid's spacing ``h`` sets the error, about
        ``h^2`` times the surface's curvature): for linearised conditions, not for
        a verdict (that is `query`'s). Only points whose cell has exact values
        at all eight corners (near the surface or inside) and whose interpolated
        distance is below ``reach`` are returned.

        Returns
        -------
        index : (j,) int64 array
        phi : (j,) float64 array
        G : (j, 3) float64 array
            Unit gradients (outward).
        """
        Q = np.ascontiguousarray(Q, dtype=np.float64).reshape(-1, 3)
        index = np.empty(len(Q), dtype=np.int64)
        phi = np.empty(len(Q))
        G = np.empty((len(Q), 3))
        k = _interpolate_kernel(
            Q, self.lo, self.h, self._shape, self._lo_sd, self._hi_sd, float(reach), index, phi, G
        )
        return index[:k], phi[:k], G[:k]

    def query(
        self, Q: FloatArray, reach: float | FloatArray, lower: FloatArray | None = None
    ) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
        """Exact signed distance, closest point and outward direction near the surface.

        Only points whose signed distance may be below ``reach`` (by `bounds`)
        take the exact closest-point query; of those, the ones whose distance
        is below ``reach`` are returned.

        Parameters
        ----------
        Q : (k, 3) float64 array
            Points in the bone's frame.
        reach : float or (k,) float64 array
            Signed distance below which a point is returned (mesh units).
        lower : (k,) float64 array, optional
            Filled with a lower bound of every point's signed distance: the exact
            one where it was taken, the grid's elsewhere.

        Returns
        -------
        index : (j,) int64 array
            Rows of ``Q`` with signed distance below ``reach``.
        phi : (j,) float64 array
            Their signed distance (< 0 inside the bone).
        C : (j, 3) float64 array
            Closest points on the bone surface.
        N : (j, 3) float64 array
            Unit outward directions at ``C``: ``(Q - C) / phi`` where the point is
            off the surface, the pseudo-normal where it lies on it.
        """
        Q = np.ascontiguousarray(Q, dtype=np.float64)
        reach = np.broadcast_to(np.asarray(reach, dtype=np.float64), (len(Q),))
        bound, _ = self.bounds(Q)
        idx = np.flatnonzero(bound < reach)
        if lower is not None:
            lower[:] = bound
        if not len(idx):
            return idx, np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
        phi, C, N = self._signed(Q[idx])
        if lower is not None:
            lower[idx] = phi
        keep = phi < reach[idx]
        return idx[keep], phi[keep], C[keep], N[keep]

    def measure(self, Q: FloatArray) -> tuple[int, float]:
        """Count the points inside the bone and return the deepest one's depth.

        Parameters
        ----------
        Q : (k, 3) float64 array
            Points in the bone's frame.

        Returns
        -------
        n_inside : int
        max_depth : float
            0 when no point is inside.
        """
        # outside the bone's bounding box is outside the bone
        P = Q[((Q >= self.lo) & (Q <= self.hi)).all(axis=1)]
        if not len(P):
            return 0, 0.0
        lower, upper = self.bounds(P)
        inside = upper < 0
        unsure = ~inside & (lower <= 0)
        n_inside = int(inside.sum())
        depths = []
        if unsure.any():
            phi = self._signed(P[unsure])[0]
            n_inside += int((phi < 0).sum())
            depths.append(-phi[phi < 0])
        if n_inside == 0:
            return 0, 0.0
        if inside.any():
            # exact depths in order of their upper bound, until none left can beat the best
            upper_depth = -lower[inside]
            cand = P[inside]
            order = np.argsort(-upper_depth)
            found = max((x.max() for x in depths if len(x)), default=0.0)
            bar = max(found, -upper[inside].max())
            i, batch = 0, 4  # deep points cost the most; the deepest is usually among the first
            while i < len(order) and upper_depth[order[i]] >= bar:
                phi = self._signed(cand[order[i : i + batch]])[0]
                found = max(found, float(np.abs(phi).max()))
                bar = max(bar, found)
                i, batch = i + batch, 2 * batch
            return n_inside, found
        return n_inside, float(max(x.max() for x in depths if len(x)))


@numba.njit(cache=True)
def _bound_at(x, y, z, lo, h, shape, lo_sd, hi_sd):  # noqa: ANN001, ANN202 # pragma: no cover
    # a point's cell's eight corner intervals, each widened by the distance to the corner;
    # outside the grid's box: the distance to the box, no upper bound
    out = 0.0
    for a, p in ((0, x), (1, y), (2, z)):
        top = lo[a] + h * (shape[a] - 1)
        e = max(lo[a] - p, p - top, 0.0)
        out += e * e
    if out > 0.0:
        return np.sqrt(out), np.inf
    s0, s1 = shape[1] * shape[2], shape[2]
    hh = h * h
    u0, u1, u2 = (x - lo[0]) / h, (y - lo[1]) / h, (z - lo[2]) / h
    b0 = min(max(int(u0), 0), shape[0] - 2)
    b1 = min(max(int(u1), 0), shape[1] - 2)
    b2 = min(max(int(u2), 0), shape[2] - 2)
    f0, f1, f2 = u0 - b0, u1 - b1, u2 - b2
    best_lo, best_hi = -np.inf, np.inf
    for c0 in range(2):
        a0 = (f0 * f0 if c0 == 0 else (1 - f0) ** 2) * hh
        for c1 in range(2):
            a1 = (f1 * f1 if c1 == 0 else (1 - f1) ** 2) * hh
            for c2 in range(2):
                a2 = (f2 * f2 if c2 == 0 else (1 - f2) ** 2) * hh
                d = np.sqrt(a0 + a1 + a2)
                k = (b0 + c0) * s0 + (b1 + c1) * s1 + b2 + c2
                best_lo = max(best_lo, np.float64(lo_sd[k]) - d)
                best_hi = min(best_hi, np.float64(hi_sd[k]) + d)
    return best_lo, best_hi


@numba.njit(cache=True)
def _bounds_kernel(P, lo, h, shape, lo_sd, hi_sd, lower, upper):  # noqa: ANN001, ANN202 # pragma: no cover
    for i in range(P.shape[0]):
        lower[i], upper[i] = _bound_at(P[i, 0], P[i, 1], P[i, 2], lo, h, shape, lo_sd, hi_sd)


@numba.njit(cache=True)
def _convexity_kernel(V, VN, ip, ix, k):  # noqa: ANN001, ANN202 # pragma: no cover
    # per vertex: the largest -2 n . d / |d|^2 over its neighbours (0 when none is below
    # its tangent plane; a vertex without a normal, as of a degenerate fan, gets 0)
    for v in range(V.shape[0]):
        n0, n1, n2 = VN[v, 0], VN[v, 1], VN[v, 2]
        r = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if not r > 0:
            continue
        n0, n1, n2 = n0 / r, n1 / r, n2 / r
        best = 0.0
        for p in range(ip[v], ip[v + 1]):
            w = ix[p]
            d0, d1, d2 = V[w, 0] - V[v, 0], V[w, 1] - V[v, 1], V[w, 2] - V[v, 2]
            dd = d0 * d0 + d1 * d1 + d2 * d2
            if dd > 0:
                best = max(best, -2.0 * (n0 * d0 + n1 * d1 + n2 * d2) / dd)
        k[v] = best


@numba.njit(cache=True)
def _interpolate_kernel(Q, lo, h, shape, lo_sd, hi_sd, reach, index, phi, G):  # noqa: ANN001, ANN202 # pragma: no cover
    # per point in the grid's box whose cell has exact values at its eight corners: the
    # trilinear value and its gradient (unit); kept where below reach; returns how many
    s0, s1 = shape[1] * shape[2], shape[2]
    k = 0
    for i in range(Q.shape[0]):
        inside = True
        for a in range(3):
            if not (lo[a] <= Q[i, a] <= lo[a] + h * (shape[a] - 1)):
                inside = False
        if not inside:
            continue
        u0, u1, u2 = (Q[i, 0] - lo[0]) / h, (Q[i, 1] - lo[1]) / h, (Q[i, 2] - lo[2]) / h
        b0 = min(max(int(u0), 0), shape[0] - 2)
        b1 = min(max(int(u1), 0), shape[1] - 2)
        b2 = min(max(int(u2), 0), shape[2] - 2)
        fx, fy, fz = u0 - b0, u1 - b1, u2 - b2
        base = b0 * s0 + b1 * s1 + b2
        exact = True
        v = np.empty(8)  # corner bits (i, j, l) in that order
        for c in range(8):
            ci, cj, cl = c >> 2, (c >> 1) & 1, c & 1
            kk = base + ci * s0 + cj * s1 + cl
            if not np.isfinite(hi_sd[kk]):
                exact = False
                break
            v[c] = lo_sd[kk]
        if not exact:
            continue
        c00 = v[0] * (1 - fz) + v[1] * fz
        c01 = v[2] * (1 - fz) + v[3] * fz
        c10 = v[4] * (1 - fz) + v[5] * fz
        c11 = v[6] * (1 - fz) + v[7] * fz
        c0 = c00 * (1 - fy) + c01 * fy
        c1 = c10 * (1 - fy) + c11 * fy
        p = c0 * (1 - fx) + c1 * fx
        if not p < reach:
            continue
        gx = c1 - c0
        gy = (c01 - c00) * (1 - fx) + (c11 - c10) * fx
        gz = ((v[1] - v[0]) * (1 - fy) + (v[3] - v[2]) * fy) * (1 - fx) + (
            (v[5] - v[4]) * (1 - fy) + (v[7] - v[6]) * fy
        ) * fx
        norm = np.sqrt(gx * gx + gy * gy + gz * gz)
        if not norm > 0:
            continue
        index[k] = i
        phi[k] = p
        G[k, 0], G[k, 1], G[k, 2] = gx / norm, gy / norm, gz / norm
        k += 1
    return k


@numba.njit(cache=True)
def _march_kernel(A, B, t0, lo, h, shape, lo_sd, hi_sd, step, t_in, t_out):  # noqa: ANN001, ANN202 # pragma: no cover
    # per way A -> B from t0 (a fraction): sphere tracing on the lower bounds until one
    # allows the inside (t_in, with t_out the last point surely outside) or the end is
    # passed (t_in = 2)
    for i in range(A.shape[0]):
        d0, d1, d2 = B[i, 0] - A[i, 0], B[i, 1] - A[i, 1], B[i, 2] - A[i, 2]
        length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        t = t0[i]
        last = t
        t_in[i] = 2.0
        while True:
            tt = min(t, 1.0)
            lb, _ = _bound_at(
                A[i, 0] + tt * d0, A[i, 1] + tt * d1, A[i, 2] + tt * d2, lo, h, shape, lo_sd, hi_sd
            )
            if lb <= 0.0:
                t_in[i] = tt
                break
            if tt >= 1.0 or length == 0.0:
                break
            last = tt
            t = tt + max(lb, step) / length
        t_out[i] = last


def _bin_points(
    R: FloatArray, radius: float
) -> tuple[IntArray, FloatArray, FloatArray, IntArray, IntArray]:
    """Points binned in cubic cells of side ``radius``: (order, points in it, corner, dims, CSR)."""
    idx = np.arange(len(R))
    lo = R.min(axis=0) if len(R) else np.zeros(3)
    ijk = np.floor((R - lo) / radius).astype(np.int64)
    dims = ijk.max(axis=0) + 1 if len(R) else np.ones(3, np.int64)
    flat = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = np.argsort(flat, kind="stable")
    indptr = np.searchsorted(flat[order], np.arange(int(np.prod(dims)) + 1))
    return idx[order], np.ascontiguousarray(R[order]), lo, dims, indptr


@numba.njit(cache=True)
def _nearest_within_kernel(Q, R, lo, h, dims, indptr, best, which):  # noqa: ANN001, ANN202 # pragma: no cover
    # every binned point within h of a query point: the nearest such query point
    hh = h * h
    for q in range(Q.shape[0]):
        c0 = int(np.floor((Q[q, 0] - lo[0]) / h))
        c1 = int(np.floor((Q[q, 1] - lo[1]) / h))
        c2 = int(np.floor((Q[q, 2] - lo[2]) / h))
        for a in range(max(c0 - 1, 0), min(c0 + 2, dims[0])):
            for b in range(max(c1 - 1, 0), min(c1 + 2, dims[1])):
                for c in range(max(c2 - 1, 0), min(c2 + 2, dims[2])):
                    cell = (a * dims[1] + b) * dims[2] + c
                    for j in range(indptr[cell], indptr[cell + 1]):
                        d0, d1, d2 = R[j, 0] - Q[q, 0], R[j, 1] - Q[q, 1], R[j, 2] - Q[q, 2]
                        d = d0 * d0 + d1 * d1 + d2 * d2
                        if d <= hh and d < best[j]:
                            best[j] = d
                            which[j] = q


@numba.njit(cache=True)
def _signed_kernel(P, C, face, sq, V, F, FN, VN, EN, FE, phi, N):  # noqa: ANN001, ANN202 # pragma: no cover
    # per point: the pseudo-normal of the feature holding its closest point (a face, an
    # edge: one barycentric vanishes, a vertex: two), its side, and the outward direction
    for i in range(P.shape[0]):
        f = face[i]
        a, b, c = F[f, 0], F[f, 1], F[f, 2]
        v00 = V[b, 0] - V[a, 0]
        v01 = V[b, 1] - V[a, 1]
        v02 = V[b, 2] - V[a, 2]
        v10 = V[c, 0] - V[a, 0]
        v11 = V[c, 1] - V[a, 1]
        v12 = V[c, 2] - V[a, 2]
        v20 = C[i, 0] - V[a, 0]
        v21 = C[i, 1] - V[a, 1]
        v22 = C[i, 2] - V[a, 2]
        d00 = v00 * v00 + v01 * v01 + v02 * v02
        d01 = v00 * v10 + v01 * v11 + v02 * v12
        d11 = v10 * v10 + v11 * v11 + v12 * v12
        d20 = v20 * v00 + v21 * v01 + v22 * v02
        d21 = v20 * v10 + v21 * v11 + v22 * v12
        den = d00 * d11 - d01 * d01
        if not den > 0:
            den = 1.0
        w1 = (d11 * d20 - d01 * d21) / den
        w2 = (d00 * d21 - d01 * d20) / den
        w0 = 1.0 - w1 - w2
        z0, z1, z2 = w0 <= 1e-9, w1 <= 1e-9, w2 <= 1e-9
        nz = int(z0) + int(z1) + int(z2)
        if nz == 2:  # on a vertex: the corner whose coordinate does not vanish
            k = 0 if not z0 else (1 if not z1 else 2)
            n0, n1, n2 = VN[F[f, k], 0], VN[F[f, k], 1], VN[F[f, k], 2]
        elif nz == 1:  # on the edge opposite the vanishing corner
            opp = 0 if z0 else (1 if z1 else 2)
            e = FE[f, (opp + 1) % 3]
            n0, n1, n2 = EN[e, 0], EN[e, 1], EN[e, 2]
        else:
            n0, n1, n2 = FN[f, 0], FN[f, 1], FN[f, 2]
        x0, x1, x2 = P[i, 0] - C[i, 0], P[i, 1] - C[i, 1], P[i, 2] - C[i, 2]
        dist = np.sqrt(sq[i])
        s = -dist if x0 * n0 + x1 * n1 + x2 * n2 < 0 else dist
        phi[i] = s
        scale = 1.0 + max(abs(P[i, 0]), abs(P[i, 1]), abs(P[i, 2]))
        if dist > 1e-12 * scale:
            N[i, 0], N[i, 1], N[i, 2] = x0 / s, x1 / s, x2 / s
        else:  # on the surface: the face's normal
            m0, m1, m2 = FN[f, 0], FN[f, 1], FN[f, 2]
            r = max(np.sqrt(m0 * m0 + m1 * m1 + m2 * m2), 1e-300)
            N[i, 0], N[i, 1], N[i, 2] = m0 / r, m1 / r, m2 / r


def _round(x: FloatArray, direction: int) -> FloatArray:
    """float32 copy of ``x`` rounded toward -inf (direction -1) or +inf (+1)."""
    y = x.astype(np.float32)
    if direction < 0:
        return np.where(y > x, np.nextafter(y, np.float32(-np.inf)), y)
    return np.where(y < x, np.nextafter(y, np.float32(np.inf)), y)

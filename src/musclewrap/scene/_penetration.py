"""Muscle-bone penetration: which muscle vertices lie inside a bone, and how deep."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = ["BoneProbe"]


class BoneProbe:
    """Inside test and depth of query points against one closed bone surface.

    Built once per bone (in the bone's own frame); `measure` is called per
    frame with the muscle's vertices expressed in that frame.

    Parameters
    ----------
    V : (n, 3) float64 array
        Bone vertices.
    F : (m, 3) int array
        Bone triangles, outward oriented.
    max_grid_nodes : int, optional
        Size of the coarse occupancy grid that classifies points far from the
        surface.

    Notes
    -----
    Points that round to a grid node with no bone vertex within two nodes,
    and outside the bone, are outside (no vertex within ``h``). Points within
    one grid spacing ``h`` of a bone vertex are classified
    exactly: the closest point on the surface (an AABB tree) and the sign of
    the angle-weighted pseudo-normal of the closest feature (face, edge or
    vertex; Baerentzen & Aanaes 2005). Points farther than ``h`` from every
    bone vertex take the side of the nearest node of a grid of spacing ``h``
    whose inside/outside comes from generalized winding numbers (Jacobson et
    al. 2013), robust to the small holes of segmented bones. Since such a
    node is within ``h*sqrt(3)/2 < h`` of the point, it lies on the same side
    of the surface. Depths are exact distances to the surface.
    """

    def __init__(self, V: FloatArray, F: IntArray, *, max_grid_nodes: int = 200_000) -> None:
        import igl
        from scipy.spatial import cKDTree

        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        self.lo, self.hi = self.V.min(axis=0), self.V.max(axis=0)
        ext = self.hi - self.lo
        e = np.linalg.norm(self.V[self.F[:, 1]] - self.V[self.F[:, 0]], axis=1).mean()
        self.h = float(max((np.prod(ext) / max_grid_nodes) ** (1 / 3), 2.0 * e))
        self._kd = cKDTree(self.V)
        self._tree = igl.AABB()
        self._tree.init(self.V, self.F)
        FN = igl.per_face_normals(self.V, self.F, np.array([0.0, 0.0, 1.0]))
        self._FN = FN
        self._VN = igl.per_vertex_normals(
            self.V, self.F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_ANGLE
        )
        # edge pseudo-normals: sum of the two adjacent face normals, keyed by sorted vertex pair
        E = np.sort(self.F[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
        key = E[:, 0] * len(self.V) + E[:, 1]
        uniq, inv = np.unique(key, return_inverse=True)
        EN = np.zeros((len(uniq), 3))
        np.add.at(EN, inv, np.repeat(FN, 3, axis=0))
        self._edge_keys, self._EN = uniq, EN
        shape = np.maximum(np.ceil(ext / self.h).astype(int) + 1, 2)
        axes = [self.lo[i] + self.h * np.arange(shape[i]) for i in range(3)]
        G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        wn = igl.fast_winding_number(self.V, self.F, G)
        self._inside = (wn > 0.5).reshape(tuple(shape))
        self._shape = shape
        # Nodes that may have a bone vertex within h of a point rounding to them: a vertex
        # within h of a point is at most 2 nodes away along each axis.
        from scipy.ndimage import binary_dilation

        occupied = np.zeros(tuple(shape), dtype=bool)
        idx = np.clip(np.rint((self.V - self.lo) / self.h).astype(int), 0, shape - 1)
        occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
        self._candidate = binary_dilation(occupied, np.ones((5, 5, 5), bool)) | self._inside

    def _pseudo_normal_sign(self, Q: FloatArray, C: FloatArray, face: IntArray) -> FloatArray:
        tri = self.V[self.F[face]]
        # barycentric coordinates of the closest points
        v0, v1 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        v2 = C - tri[:, 0]
        d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        den = np.where(d00 * d11 - d01 * d01 > 0, d00 * d11 - d01 * d01, 1.0)
        b1 = (d11 * d20 - d01 * d21) / den
        b2 = (d00 * d21 - d01 * d20) / den
        b = np.stack([1 - b1 - b2, b1, b2], axis=1)
        eps = 1e-9
        zero = b <= eps
        N = self._FN[face].copy()
        nz = zero.sum(1)
        # on a vertex: two barycentrics vanish
        at_v = nz == 2
        if at_v.any():
            corner = np.argmax(~zero[at_v], axis=1)
            N[at_v] = self._VN[self.F[face[at_v], corner]]
        at_e = nz == 1
        if at_e.any():
            opp = np.argmax(zero[at_e], axis=1)
            f = self.F[face[at_e]]
            a = f[np.arange(len(f)), (opp + 1) % 3]
            c = f[np.arange(len(f)), (opp + 2) % 3]
            k = np.minimum(a, c) * len(self.V) + np.maximum(a, c)
            N[at_e] = self._EN[np.searchsorted(self._edge_keys, k)]
        return np.einsum("ij,ij->i", Q - C, N)

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
        box = ((Q >= self.lo - self.h) & (Q <= self.hi + self.h)).all(axis=1)
        if not box.any():
            return 0, 0.0
        P = Q[box]
        idx = np.clip(np.rint((P - self.lo) / self.h).astype(int), 0, self._shape - 1)
        P = P[self._candidate[idx[:, 0], idx[:, 1], idx[:, 2]]]
        if not len(P):
            return 0, 0.0
        d, _ = self._kd.query(P, distance_upper_bound=self.h)
        near = np.isfinite(d)
        inside = np.zeros(len(P), dtype=bool)
        if (~near).any():
            idx = np.rint((P[~near] - self.lo) / self.h).astype(int)
            idx = np.clip(idx, 0, self._shape - 1)
            inside[~near] = self._inside[idx[:, 0], idx[:, 1], idx[:, 2]]
        depth = np.zeros(0)
        if near.any():
            Pn = np.ascontiguousarray(P[near])
            sq, face, C = self._tree.squared_distance(self.V, self.F, Pn)
            s = self._pseudo_normal_sign(Pn, C, face)
            inside[near] = s < 0
            depth = np.sqrt(sq[s < 0])
        far_in = inside & ~near
        if far_in.any():
            sq, _, _ = self._tree.squared_distance(self.V, self.F, np.ascontiguousarray(P[far_in]))
            depth = np.concatenate([depth, np.sqrt(sq)])
        return int(inside.sum()), float(depth.max()) if len(depth) else 0.0

"""A prepared muscle's data: cage, coordinates, Laplacian and proxy, and what follows from them.

`PreparedMuscle` is what the per-pose solve (`._deformer.Deformer`) reads; `._muscle.Muscle`
adds how one is built, saved, loaded and bound to its rest lines.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy import sparse

from .._typing import FloatArray, IntArray
from .._validation import as_vertices
from ..cage import Cage
from ..contact import vertex_faces
from ..mesh import mean_edge_length, umbrella_laplacian, vertex_adjacency, vertex_areas, volume

__all__ = ["PreparedMuscle"]


@dataclass(eq=False)
class PreparedMuscle:
    """Everything computed once per muscle: cage, coordinates, Laplacian, proxy.

    Build with `Muscle.from_mesh` or `Muscle.from_file`, save with `save`,
    restore with `load`, then `bind` the rest action lines to get a `Deformer`.

    Attributes
    ----------
    V : (n, 3) float64 array
        Fine rest vertices (cleaned, outward oriented).
    F : (k, 3) int64 array
        Fine triangles.
    cage : Cage
        The verified cage.
    W : (n, m) float64 array
        Mean value coordinates of the fine vertices in the rest cage.
    L : (m, m) float64 array
        Row-normalized cotangent Laplacian of the rest cage.
    proxy_F : (p, 3) int64 array
        Triangles of the proxy mesh (a decimation of the fine mesh).
    proxy_W : (q, m) float64 array
        Mean value coordinates of the proxy's vertices.
    volume_rest : float
        Fine rest volume.
    notes : tuple of str
        What was changed on load (merged vertices, flipped orientation).
    seconds_prepare : float
        Wall time of the preparation.
    input_id : (n,) int64 array
        For each fine vertex, the vertex of the mesh as given that it is
        (`musclewrap.mesh.vertex_origins`): ``arange(n)`` where cleaning changed
        nothing, the first of merged duplicates, -1 for a vertex a repair made.
        Rows of every deformed ``V`` are in this order; written meshes carry it
        as the point array ``input_id``.
    """

    V: FloatArray
    F: IntArray
    cage: Cage
    W: FloatArray
    L: FloatArray
    proxy_F: IntArray
    proxy_W: FloatArray
    volume_rest: float
    notes: tuple[str, ...] = ()
    seconds_prepare: float = 0.0
    source: str = "mesh"
    input_id: IntArray | None = None
    proxy_volume_rest: float = field(init=False)
    proxy_W_T: FloatArray = field(init=False, repr=False)
    delta_rest: FloatArray = field(init=False)

    def __post_init__(self) -> None:
        if self.input_id is None:
            self.input_id = np.arange(len(self.V), dtype=np.int64)
        self.input_id = np.asarray(self.input_id, dtype=np.int64)
        if self.input_id.shape != (len(self.V),):
            raise ValueError(
                f"input_id has shape {self.input_id.shape}, the muscle has {len(self.V)} vertices"
            )
        C = self.cage.C
        self.delta_rest = self.L @ C
        self._center = C.mean(axis=0)
        self.proxy_W_T = np.ascontiguousarray(self.proxy_W.T)
        self.proxy_volume_rest = volume(
            self.proxy_W @ (C - self._center), self.proxy_F, center=np.zeros(3)
        )

    @property
    def W_T(self) -> FloatArray:
        """Contiguous transpose of `W` (built on first use; reference solvers only)."""
        if getattr(self, "_W_T", None) is None:
            self._W_T = np.ascontiguousarray(self.W.T)
        return self._W_T

    def shape_change(self, V: npt.ArrayLike) -> FloatArray:
        """Per-vertex change of local shape, in mean rest edge lengths (spike measure).

        With ``delta_i = v_i - mean(1-ring of v_i)`` (uniform Laplacian of the
        fine mesh), returns ``| |delta_i(V)| - |delta_i(rest)| |`` divided by
        the mean rest edge length. Zero under a rigid motion; a spike or a
        crease shows up as a large value at its vertices.

        Parameters
        ----------
        V : (n, 3) array_like
            Deformed positions of the fine vertices.

        Returns
        -------
        (n,) float64 array
        """
        U, d0, edge = self._umbrella_rest()
        V = self._positions(V)
        return np.abs(np.linalg.norm(U @ V, axis=1) - d0) / edge

    @property
    def umbrella(self) -> sparse.csr_matrix:
        """The fine mesh's uniform Laplacian (`shape_change`'s; built on first use)."""
        return self._umbrella_rest()[0]

    @property
    def umbrella_rest_lengths(self) -> FloatArray:
        """The lengths of `umbrella`'s vectors at rest (what `shape_change` measures from)."""
        return self._umbrella_rest()[1]

    def _umbrella_rest(self) -> tuple[sparse.csr_matrix, FloatArray, float]:
        """The uniform Laplacian, its vectors' lengths at rest and the mean rest edge."""
        if getattr(self, "_umbrella", None) is None:
            U = umbrella_laplacian(self.F, len(self.V))
            self._umbrella = (
                U,
                np.linalg.norm(U @ self.V, axis=1),
                mean_edge_length(self.V, self.F),
            )
        return self._umbrella

    def _positions(self, V: npt.ArrayLike) -> FloatArray:
        """``V`` checked as positions of the fine vertices (the rest mesh's shape)."""
        V = as_vertices(V, "V")
        if V.shape != self.V.shape:
            raise ValueError(f"V has shape {V.shape}, the muscle has {self.V.shape}")
        return V

    def area_stretch(self, V: npt.ArrayLike) -> FloatArray:
        """Per-vertex stretch of the surface: its area around the vertex over the rest one.

        A vertex's area is a third of its triangles'. 1 under a rigid motion; above 1
        where the surface is stretched (the outside of a bend, a muscle lengthened at
        constant volume: ``sqrt`` of its stretch), below where it is compressed.

        Parameters
        ----------
        V : (n, 3) array_like
            Deformed positions of the fine vertices.

        Returns
        -------
        (n,) float64 array
        """
        V = self._positions(V)
        if getattr(self, "_rest_areas", None) is None:
            self._rest_areas = vertex_areas(self.V, self.F)
        return vertex_areas(V, self.F) / self._rest_areas

    @property
    def vertex_faces(self) -> tuple[IntArray, IntArray]:
        """The faces of each fine vertex, CSR ``(indptr, indices)`` (the contact finish)."""
        if getattr(self, "_vertex_faces", None) is None:
            self._vertex_faces = vertex_faces(self.F, len(self.V))
        return self._vertex_faces

    @property
    def adjacency(self) -> sparse.csr_matrix:
        """Vertex adjacency of the fine mesh (built on first use; the contact finish)."""
        if getattr(self, "_adjacency", None) is None:
            self._adjacency = vertex_adjacency(self.F, len(self.V))
        return self._adjacency

    # ------------------------------------------------------------------ build

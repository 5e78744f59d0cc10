"""The per-muscle preparation: cage, coordinates, Laplacian and proxy, built once."""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from pathlib import Path

import igl
import numpy as np
import numpy.typing as npt

from .._hashing import digest_arrays
from .._typing import PathLike
from .._validation import as_faces, as_vertices
from ..cage import Cage, build_cage
from ..conditions import (
    cotangent_laplacian,
)
from ..constants import defaults
from ..coordinates import mean_value_coordinates
from ..mesh import (
    atomic_path,
    check_memory,
    check_mesh,
    clean_mesh,
    vertex_origins,
    volume,
)
from ._deformer import Deformer
from ._prepared import PreparedMuscle
from ._result import DeformationResult

__all__ = ["Muscle", "deform"]

#: the format of a cached preparation (its file says it; another is prepared anew)
PREPARATION_FORMAT = 4  # 4: input_id


class Muscle(PreparedMuscle):
    """Everything computed once per muscle: cage, coordinates, Laplacian, proxy.

    Build with `Muscle.from_mesh` or `Muscle.from_file`, save with `save`,
    restore with `load`, then `bind` the rest action lines to get a `Deformer`.
    Its data and what follows from them (`shape_change`, `area_stretch`, the
    adjacency): `PreparedMuscle`.
    """

    @classmethod
    def from_mesh(
        cls,
        V: npt.ArrayLike,
        F: npt.ArrayLike,
        *,
        cage_size: int = defaults.cage_size,
        cage_offset: float | None = None,
        cage_coarsening: str = "uniform",
        source: str = "mesh",
        cleaned: bool = False,
        input_id: npt.ArrayLike | None = None,
        cage_around: npt.ArrayLike | None = None,
    ) -> Muscle:
        """Prepare a muscle from its rest-pose surface.

        Parameters
        ----------
        V : (n, 3) array_like
            Vertices of a closed triangle mesh.
        F : (k, 3) array_like
            Triangles.
        cage_size : int, optional
            Target number of cage vertices.
        cage_offset : float, optional
            Cage offset in mesh units (see `musclewrap.cage.build_cage`).
        cage_coarsening : {"uniform", "quadric"}, optional
            How the cage is coarsened (see `musclewrap.cage.build_cage`).
        source : str, optional
            Name quoted in messages (e.g. the file name).
        cleaned : bool, optional
            ``V, F`` come from `musclewrap.mesh.clean_mesh` already (a scene
            cleans each mesh once, when reading it, and caches the result):
            its checks are not repeated.
        input_id : (n,) int array_like, optional
            With ``cleaned``: each vertex's index in the mesh as it was read
            (`musclewrap.mesh.vertex_origins`); default ``arange(n)``. Without
            ``cleaned`` it is found here, against ``V`` as given.

        Returns
        -------
        Muscle

        Raises
        ------
        musclewrap.mesh.MeshError
            If the mesh is not a closed, consistently oriented 2-manifold.
        musclewrap.cage.CageError
            If no valid cage could be built.
        """
        t0 = time.perf_counter()
        V = as_vertices(V, "V")
        F = as_faces(F, len(V), "F")
        if cleaned:
            check_memory(len(F), source)
            notes: list[str] = []
        else:
            V_in = V
            V, F, notes = clean_mesh(V, F, source=source)  # checks the memory first
            input_id = vertex_origins(V_in, V)
        around = V
        if cage_around is not None:
            if not cleaned:
                raise ValueError("cage_around needs cleaned=True (the vertices as given)")
            around = as_vertices(cage_around, "cage_around")
            if around.shape != V.shape:
                raise ValueError(f"cage_around has shape {around.shape}, V has {V.shape}")
        cage = build_cage(around, F, size=cage_size, offset=cage_offset, coarsening=cage_coarsening)
        W = mean_value_coordinates(V, cage.C, cage.CF)
        L = cotangent_laplacian(cage.C, cage.CF)
        if len(F) > 2 * defaults.proxy_size:
            PV, PF, _, _ = igl.decimate(
                np.asfortranarray(V),
                np.asfortranarray(F.astype(np.int32)),
                defaults.proxy_size,
                False,
            )
            PV = np.ascontiguousarray(PV)
            PF = np.ascontiguousarray(PF, dtype=np.int64)
            if not check_mesh(PV, PF).closed:
                PV, PF = V, F
            PW = W if PV is V else mean_value_coordinates(PV, cage.C, cage.CF)
        else:
            PF, PW = F, W
        return cls(
            V=V,
            F=F,
            cage=cage,
            W=W,
            L=L,
            proxy_F=PF,
            proxy_W=PW,
            volume_rest=volume(V, F),
            notes=tuple(notes),
            seconds_prepare=time.perf_counter() - t0,
            source=source,
            input_id=None if input_id is None else np.asarray(input_id, dtype=np.int64),
        )

    @classmethod
    def from_file(cls, path: PathLike, **kwargs: object) -> Muscle:
        """Read a mesh file (see `musclewrap.mesh.read_mesh`) and prepare it."""
        from ..mesh import read_mesh

        V, F = read_mesh(path)
        return cls.from_mesh(V, F, source=str(path), **kwargs)  # type: ignore[arg-type]

    # ------------------------------------------------------------- save/load
    def content_hash(self) -> str:
        """SHA-256 over every array of the preparation (names, dtypes, shapes and bytes)."""
        return digest_arrays(self._arrays())

    def _arrays(self) -> dict[str, np.ndarray]:
        c = self.cage
        return {
            "V": self.V,
            "F": self.F,
            "C": c.C,
            "CF": c.CF,
            "W": self.W,
            "L": self.L,
            "proxy_F": self.proxy_F,
            "proxy_W": self.proxy_W,
            "input_id": self.input_id,
        }

    def save(self, path: PathLike) -> Path:
        """Save the preparation to an ``.npz`` file (written atomically)."""
        c = self.cage
        meta = {
            "format": PREPARATION_FORMAT,
            "notes": list(self.notes),
            "source": self.source,
            "seconds_prepare": self.seconds_prepare,
            "content_sha256": self.content_hash(),
            "cage": {
                k: getattr(c, k)
                for k in (
                    "offset",
                    "min_distance",
                    "min_winding",
                    "volume_ratio",
                    "min_angle_deg",
                    "push_rounds",
                    "method",
                )
            },
        }
        p = Path(path)
        with atomic_path(p) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **self._arrays(), meta=np.array(json.dumps(meta)))
        return p

    @classmethod
    def load(cls, path: PathLike) -> Muscle:
        """Load a preparation saved by `save`, verifying its integrity.

        Raises
        ------
        ValueError
            If the file is missing, not a musclewrap preparation, of another
            format version, or its content does not match its stored hash.
        """
        p = Path(path)
        if not p.is_file():
            raise ValueError(f"{p}: no such prepared-muscle file")
        try:
            with open(p, "rb") as fh, np.load(fh, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
            meta = json.loads(str(data["meta"]))
        except Exception as exc:  # noqa: BLE001 - any damage is reported the same way
            raise ValueError(f"{p}: not a readable musclewrap preparation ({exc})") from None
        if meta.get("format") != PREPARATION_FORMAT:
            raise ValueError(
                f"{p}: preparation format {meta.get('format')} is not "
                f"{PREPARATION_FORMAT}; run prepare again"
            )
        cage = Cage(C=data["C"], CF=data["CF"], **meta["cage"])
        m = cls(
            V=data["V"],
            F=data["F"],
            cage=cage,
            W=data["W"],
            L=data["L"],
            proxy_F=data["proxy_F"],
            proxy_W=data["proxy_W"],
            volume_rest=volume(data["V"], data["F"]),
            notes=tuple(meta["notes"]),
            seconds_prepare=float(meta["seconds_prepare"]),
            source=meta["source"],
            input_id=data["input_id"],
        )
        if m.content_hash() != meta.get("content_sha256"):
            raise ValueError(
                f"{p}: content does not match its stored hash (corrupted); run prepare again"
            )
        return m

    # ------------------------------------------------------------------ bind
    def bind(
        self,
        rest_lines: Mapping[str, npt.ArrayLike],
        *,
        reference_point: npt.ArrayLike | None = None,
        skeleton_weight: float = defaults.skeleton_weight,
        anchors: npt.ArrayLike | None = None,
        line_reach: float | None = defaults.line_reach,
        line_window: float = defaults.line_window,
        attached: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    ) -> Deformer:
        """Attach the rest-pose action lines; returns the per-pose solver.

        Parameters
        ----------
        rest_lines : mapping of str to (k, 3) array_like
            Action lines in the rest pose, by name.
        reference_point : (3,) array_like, optional
            Rest position of the reference point (e.g. the centroid of the
            bone the muscle runs along); pass its current position to every
            `Deformer.deform` call.
        skeleton_weight : float, optional
            Weight of the skeleton condition relative to the Laplacian.
        anchors : (k,) int array_like, optional
            Fine vertices that keep their rest positions (soft, like the skeleton
            condition): where the muscle lies on a bone of the body that carries
            it (an origin), in the frame in which it is deformed.
        line_reach : float or None, optional
            A line's samples beyond the first or last that lies within this many
            of the muscle's mean thicknesses (``4 V / A``) outside it are not bound
            (tendons the mesh does not hold; `Deformer.unbound` says which). None
            binds every sample.
        line_window : float, optional
            Each sample of a current line is the line's mean over a window of this many
            sample spacings either side (`musclewrap.conditions.window_mean`): the
            deformation then has no kink where a point of the path slides past a sample
            (the fibres' moment arms no step); 0 (the default): the line's point.
        attached : (origin, insertion) int array_likes, optional
            Fine vertices held to the lines' first (origin) and last (insertion) points,
            turning with the lines' end segments: the muscle's attachment areas
            (`Deformer`).

        Returns
        -------
        Deformer
        """
        return Deformer(
            self,
            rest_lines,
            reference_point=reference_point,
            skeleton_weight=skeleton_weight,
            anchors=anchors,
            line_reach=line_reach,
            line_window=line_window,
            attached=attached,
        )


def deform(
    V: npt.ArrayLike,
    F: npt.ArrayLike,
    rest_lines: Mapping[str, npt.ArrayLike],
    current_lines: Mapping[str, npt.ArrayLike],
    *,
    reference_rest: npt.ArrayLike | None = None,
    reference_current: npt.ArrayLike | None = None,
    cage_size: int = defaults.cage_size,
    method: str = "sqp",
) -> DeformationResult:
    """Deform one muscle to one pose (prepares, binds and solves in one call).

    For many poses build a `Muscle` once and reuse its `Deformer`.

    Parameters
    ----------
    V : (n, 3) array_like
        Rest vertices of a closed muscle surface.
    F : (k, 3) array_like
        Triangles.
    rest_lines, current_lines : mapping of str to (k, 3) array_like
        Action lines in the rest and the current pose.
    reference_rest, reference_current : (3,) array_like, optional
        Reference point in both poses.
    cage_size : int, optional
        Target number of cage vertices.
    method : str, optional
        See `Deformer.deform`.

    Returns
    -------
    DeformationResult
    """
    muscle = Muscle.from_mesh(V, F, cage_size=cage_size)
    return muscle.bind(rest_lines, reference_point=reference_rest).deform(
        current_lines, reference_point=reference_current, method=method
    )

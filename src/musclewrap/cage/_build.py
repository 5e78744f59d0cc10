"""Construction and verification of the coarse envelope (cage) of a muscle."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import igl
import numpy as np

from .._typing import FloatArray, IntArray
from ..constants import defaults, tol
from ..mesh import (
    check_mesh,
    mean_thickness,
    self_intersecting_faces,
    vertex_normals,
    volume,
)

__all__ = ["Cage", "CageError", "build_cage", "cage_self_intersections", "verify_cage"]


class CageError(RuntimeError):
    """The cage could not be built or does not meet its guarantees."""


@dataclass(frozen=True)
class Cage:
    """A verified coarse envelope of a fine mesh.

    Attributes
    ----------
    C : (m, 3) float64 array
        Cage vertices.
    CF : (k, 3) int64 array
        Cage triangles, outward oriented.
    offset : float
        Distance of the offset surface the cage was decimated from.
    min_distance : float
        Smallest distance from a fine vertex to the cage (the verified margin).
    min_winding : float
        Smallest generalized winding number of a fine vertex (1 = inside).
    volume_ratio : float
        Cage volume over fine volume.
    min_angle_deg : float
        Smallest triangle angle of the cage, in degrees.
    push_rounds : int
        Rounds of pushing vertices outward that enclosure needed.
    method : str
        How the offset surface was coarsened: ``"uniform"`` (clustering into
        cells of equal area, well-shaped triangles) or ``"quadric"`` (quadric
        error decimation, the fallback when the uniform remesh is not a
        valid 2-manifold).
    """

    C: FloatArray
    CF: IntArray
    offset: float
    min_distance: float
    min_winding: float
    volume_ratio: float
    min_angle_deg: float
    push_rounds: int
    method: str = "uniform"


def _min_angle_deg(C: FloatArray, CF: IntArray) -> float:
    a, b, c = C[CF[:, 0]], C[CF[:, 1]], C[CF[:, 2]]
    angles = []
    for p, q, r in ((a, b, c), (b, c, a), (c, a, b)):
        u, v = q - p, r - p
        cosang = np.einsum("ij,ij->i", u, v) / (
            np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)
        )
        angles.append(np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))))
    return float(np.min(angles))


def cage_self_intersections(C: FloatArray, CF: IntArray) -> int:
    """Count cage triangles that cross a triangle they share no vertex with.

    The mesh check `musclewrap.mesh.self_intersecting_faces`, applied to the cage.

    Parameters
    ----------
    C : (m, 3) float64 array
        Cage vertices.
    CF : (k, 3) int array
        Cage triangles.

    Returns
    -------
    int
        Number of crossing triangles (0 for a valid cage).
    """
    return self_intersecting_faces(C, CF)


def _enclosure(
    V: FloatArray, C: FloatArray, CF: IntArray
) -> tuple[FloatArray, FloatArray, IntArray]:
    wn = igl.winding_number(C, CF, V)
    d2, face, _ = igl.point_mesh_squared_distance(V, C, CF)
    return wn, np.sqrt(d2), face


def verify_cage(V: FloatArray, C: FloatArray, CF: IntArray, *, margin: float) -> list[str]:
    """List every way a cage fails its guarantees (empty list = valid).

    Parameters
    ----------
    V : (n, 3) float64 array
        Fine vertices.
    C, CF : arrays
        Cage.
    margin : float
        Required distance from every fine vertex to the cage.

    Returns
    -------
    list of str
        Problems: not a closed oriented manifold, self-intersections, fine
        vertices outside (winding number < 0.5) or closer than ``margin``.
    """
    wn, dist, _ = _enclosure(V, C, CF)
    return _problems(C, CF, wn, dist, margin, cage_self_intersections(C, CF))


def _problems(
    C: FloatArray, CF: IntArray, wn: FloatArray, dist: FloatArray, margin: float, n_self: int
) -> list[str]:
    problems = []
    chk = check_mesh(C, CF)
    if not chk.ok:
        problems.append("cage: " + "; ".join(chk.problems()))
    if n_self:
        problems.append(f"cage has {n_self} self-intersecting triangle(s)")
    outside = int(np.sum(wn < tol.winding_inside))
    if outside:
        problems.append(f"{outside} fine vertices lie outside the cage")
    close = int(np.sum(dist < margin))
    if close:
        problems.append(f"{close} fine vertices are closer than {margin:.3g} to the cage")
    return problems


def _uniform_remesh(SV: FloatArray, SF: IntArray, size: int) -> tuple[FloatArray, IntArray]:
    """Remesh a closed surface into ``size`` vertices of (nearly) equal area.

    Approximated centroidal Voronoi clustering (pyacvd): every output vertex
    is the centroid of a patch of equal area, so triangles are well shaped
    and spread evenly along the whole muscle.
    """
    import pyacvd
    import pyvista as pv

    mesh = pv.PolyData.from_regular_faces(SV, SF.astype(np.int64))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clus = pyacvd.Clustering(mesh)
        # enough input points per cluster for equal-area patches
        if mesh.n_points < 20 * size:
            clus.subdivide(int(np.ceil(np.log2(20 * size / mesh.n_points) / 2)))
        clus.cluster(size)
        out = clus.create_mesh()
    C = np.ascontiguousarray(out.points, dtype=np.float64)
    CF = np.ascontiguousarray(out.regular_faces, dtype=np.int64)
    return C, CF


def _quadric_decimate(SV: FloatArray, SF: IntArray, size: int) -> tuple[FloatArray, IntArray]:
    """Quadric-error decimation to ``size`` vertices that refuses self-intersections."""
    target_faces = 2 * size - 4
    SVf, SFf = np.asfortranarray(SV), np.asfortranarray(SF.astype(np.int32))
    if len(SF) > 8 * target_faces:
        # A first, unconstrained pass is fast; the final collapses block self-intersections.
        SVf, SFf, _, _ = igl.qslim(SVf, SFf, 8 * target_faces, False)
        SVf, SFf = np.asfortranarray(SVf), np.asfortranarray(SFf.astype(np.int32))
    C, CF, _, _ = igl.qslim(SVf, SFf, target_faces, True)
    return np.ascontiguousarray(C, dtype=np.float64), np.ascontiguousarray(CF, dtype=np.int64)


def _coarsen(
    SV: FloatArray, SF: IntArray, size: int, coarsening: str
) -> tuple[FloatArray, IntArray, str]:
    """Coarse, self-intersection-free closed 2-manifold from the offset surface.

    Uniform remeshing first: quadric decimation keeps almost no vertices on
    flat or cylindrical stretches and joins what it keeps by slivers, and such
    a cage cannot bend in the middle (compare the smallest angle, fit and
    shape change of ``musclewrap bench capsule --cage-coarsening quadric``).
    Quadric decimation remains the fallback.
    """
    if coarsening == "uniform":
        for n in (size, int(round(1.1 * size)), int(round(0.9 * size))):
            C, CF = _uniform_remesh(SV, SF, n)
            if len(CF) and check_mesh(C, CF).ok and cage_self_intersections(C, CF) == 0:
                return C, CF, "uniform"
    C, CF = _quadric_decimate(SV, SF, size)
    if cage_self_intersections(C, CF):
        raise CageError("quadric decimation of the offset surface self-intersects")
    return C, CF, "quadric"


def build_cage(
    V: FloatArray,
    F: IntArray,
    *,
    size: int = defaults.cage_size,
    offset: float | None = None,
    coarsening: str = "uniform",
    max_push_rounds: int = 12,
) -> Cage:
    """Build a verified cage around a closed fine mesh.

    An offset surface at distance ``offset`` is extracted from a signed
    distance grid (marching cubes), remeshed into about ``size`` vertices of
    equal area (approximated centroidal Voronoi clustering; quadric
    decimation that refuses self-intersections as the fallback), and then
    checked: it must be a
    closed, outward-oriented, self-intersection-free 2-manifold, enclose every
    fine vertex (generalized winding number) and keep them at least
    ``defaults.cage_margin * offset`` away. Vertices too close are pushed
    outward along their normals until that holds.

    Parameters
    ----------
    V : (n, 3) float64 array
        Fine vertices of a closed, outward-oriented mesh.
    F : (k, 3) int array
        Fine triangles.
    size : int, optional
        Target number of cage vertices (at least 20).
    offset : float, optional
        Offset distance in mesh units. Default: ``defaults.cage_offset`` times
        the mean thickness ``4 V / A``, at most ``defaults.cage_offset_max``
        times the bounding-box diagonal.
    coarsening : {"uniform", "quadric"}, optional
        ``"uniform"`` (default): equal-area clustering, quadric decimation
        only if that fails; ``"quadric"``: quadric decimation (for comparison).
    max_push_rounds : int, optional
        Limit of the enclosure repair loop.

    Returns
    -------
    Cage

    Raises
    ------
    CageError
        If no valid cage results.

    Notes
    -----
    Decimating first and pushing along normals afterwards fails on thin,
    tendinous muscles (measured on the LHDL psoas: a cage of 35 times the
    muscle's volume with flipped faces); the offset surface avoids that.
    """
    if size < 20:
        raise ValueError(f"size must be at least 20 cage vertices, got {size}")
    if coarsening not in ("uniform", "quadric"):
        raise ValueError(f"coarsening must be 'uniform' or 'quadric', got {coarsening!r}")
    # Where the verified cage cannot be had at the requested size (a vertex still too near
    # after the push rounds: seen on a muscle flattened against a bone by the contact
    # finish), other sizes and then quadric decimation are tried before giving up.
    tries = [(size, coarsening)]
    if coarsening == "uniform":
        tries += [(int(round(1.3 * size)), "uniform"), (int(round(0.8 * size)), "uniform")]
        tries += [(size, "quadric")]
    for k, (n, how) in enumerate(tries):
        try:
            return _build_cage(V, F, n, offset, how, max_push_rounds)
        except CageError:
            if k == len(tries) - 1:
                raise
    raise AssertionError("unreachable")  # pragma: no cover


def _build_cage(
    V: FloatArray,
    F: IntArray,
    size: int,
    offset: float | None,
    coarsening: str,
    max_push_rounds: int,
) -> Cage:
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    longest = float(np.max(V.max(0) - V.min(0)))
    vol = volume(V, F)
    if offset is None:
        offset = min(
            defaults.cage_offset * mean_thickness(V, F, vol), defaults.cage_offset_max * diag
        )
    if not offset > 0:
        raise ValueError(f"offset must be positive, got {offset}")
    spacing = max(offset / 1.2, longest / 160.0)
    offset = max(offset, 1.2 * spacing)
    cells = int(np.ceil((longest + 4 * offset) / spacing))
    SV, SF, _, _, _ = igl.offset_surface(
        V, F, offset, cells, igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER
    )
    if len(SF) == 0:
        raise CageError("the offset surface is empty (is the mesh closed?)")
    C, CF, method = _coarsen(SV, SF.astype(np.int64), size, coarsening)
    if volume(C, CF) < 0:
        CF = CF[:, ::-1].copy()
    margin = defaults.cage_margin * offset
    rounds = 0
    for rounds in range(max_push_rounds + 1):
        # signed distance with pseudo-normal signs (exact for a closed 2-manifold,
        # 3x cheaper than winding numbers); negative inside
        sd, face, _, _ = igl.signed_distance(
            V, C, CF, sign_type=igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL
        )
        bad = sd > -margin
        if not bad.any() or rounds == max_push_rounds:
            break
        # Push the vertices of the cage faces nearest to offending fine vertices
        # (by distance + margin when outside, margin - distance when inside).
        need = sd[bad] + margin
        push = np.zeros(len(C))
        for k in range(3):
            np.maximum.at(push, CF[face[bad], k], need)
        # twice the need: a vertex normal meets the nearest face at an angle, so the face
        # moves less than its corners (Cage.push_rounds records how many rounds it took)
        C = C + vertex_normals(C, CF) * (2.0 * push + 1e-3 * offset * (push > 0))[:, None]
    # the final verdict uses generalized winding numbers, whatever the cage's state
    wn, dist, _ = _enclosure(V, C, CF)
    # _coarsen checked for self-intersections; only pushing can have made some
    n_self = cage_self_intersections(C, CF) if rounds else 0
    problems = _problems(C, CF, wn, dist, margin, n_self)
    if problems:
        raise CageError("could not build a valid cage: " + "; ".join(problems))
    return Cage(
        C=C,
        CF=CF,
        offset=float(offset),
        min_distance=float(dist.min()),
        min_winding=float(wn.min()),
        volume_ratio=float(volume(C, CF) / vol),
        min_angle_deg=_min_angle_deg(C, CF),
        push_rounds=rounds,
        method=method,
    )

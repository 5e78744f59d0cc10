"""A mesh made usable or refused: checked, tidied, oriented, repaired where asked."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ._checks import (
    MeshError,
    check_memory,
    check_mesh,
    orient_faces,
    self_intersecting_faces,
    split_nonmanifold_vertices,
    tidy_mesh,
)
from ._repair import repair_mesh

__all__ = ["clean_mesh"]


def clean_mesh(
    V: FloatArray, F: IntArray, *, source: str = "mesh", repair: bool = False
) -> tuple[FloatArray, IntArray, list[str]]:
    """Make a mesh usable or refuse it with a message naming the problem.

    Merges duplicate vertices, drops faces with repeated indices, orients the
    faces of a closed surface consistently (`orient_faces`) and outward, and
    refuses anything that is not a closed, single-component 2-manifold without
    self-intersections.

    Parameters
    ----------
    V : (n, 3) float64 array
        Vertex positions.
    F : (m, 3) int array
        Triangles.
    source : str, optional
        File name or label quoted in messages.
    repair : bool, optional
        Repair a non-manifold, open or multi-component mesh automatically
        instead of refusing it: vertices where sheets touch are split
        (`split_nonmanifold_vertices`), the rest goes to
        `musclewrap.mesh.repair_mesh` (PyMeshFix); the notes say what changed.

    Returns
    -------
    V, F : arrays
        The cleaned mesh, outward oriented.
    notes : list of str
        What was changed.

    Raises
    ------
    MeshError
        If the mesh is open, non-manifold, one-sided, has several components,
        passes through itself, encloses no volume, or is too large for the
        memory available (`check_memory`).
    """
    V = np.asarray(V, dtype=np.float64)
    check_memory(len(F), source)
    if not np.isfinite(V).all():
        bad = int((~np.isfinite(V).all(axis=1)).sum())
        raise MeshError(f"{source}: {bad} vertex coordinate row(s) are NaN or infinite")
    V, F, notes = tidy_mesh(V, F)
    chk = check_mesh(V, F)
    if chk.closed and chk.inconsistent_edges:
        oriented = orient_faces(F, len(V))
        if oriented is not None:  # else refused below: a one-sided surface
            F, flipped = oriented
            notes.append(
                f"{flipped} of {len(F)} faces were oriented against their neighbours: flipped"
            )
            chk = check_mesh(V, F)
    problems = chk.problems(repairable=False)
    if chk.degenerate_faces:
        notes.append(f"kept {chk.degenerate_faces} zero-area face(s) (they add no volume)")
    if problems and repair and chk.nonmanifold_vertices:
        V, F, split = split_nonmanifold_vertices(V, F)
        notes.append(
            f"split {split} non-manifold vertex(es) where sheets of the surface touch "
            "(positions and volume unchanged)"
        )
        chk = check_mesh(V, F)
        problems = chk.problems(repairable=False)
    if problems and repair:
        V, F, more = repair_mesh(V, F, source=source)
        notes += more
        chk = check_mesh(V, F)
        problems = chk.problems(repairable=False)
    if problems:
        hint = (
            "repair it first (musclewrap repairs automatically with repair=True / the scene's "
            "'repair = true'; or PyMeshFix, or MeshLab's 'remove non-manifold edges' and "
            "'close holes'), or keep only the main component"
        )
        raise MeshError(
            f"{source}: not a closed 2-manifold muscle surface: {'; '.join(problems)}; {hint}"
        )
    crossing = self_intersecting_faces(V, F)
    if crossing:
        # closed, manifold and in one piece, but its signed volume counts a fold twice or not
        raise MeshError(
            f"{source}: the surface passes through itself ({crossing} triangles cross others); "
            "its volume is not defined: fix the fold in the segmentation (or with MeshLab's "
            "'select self intersecting faces' and a local remesh)"
        )
    if chk.volume < 0:
        F = F[:, ::-1].copy()
        notes.append("faces were oriented inward: flipped to outward")
    elif chk.volume == 0:
        raise MeshError(f"{source}: the mesh encloses no volume")
    return V, np.ascontiguousarray(F), notes

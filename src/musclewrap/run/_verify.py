"""An independent check of a run's outputs: against the full-resolution bones, and each other."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .._cache import cached_measure
from .._typing import FloatArray, IntArray
from ..mesh import apply_transform, clean_mesh, read_mesh, tidy_mesh, volume
from ..scene import Scene, drive_scene
from ._read import fit_bones

__all__ = ["inside_depth", "inside_depths", "muscle_overlaps", "verify_run"]


def inside_depth(P: FloatArray, V: FloatArray, F: IntArray) -> tuple[int, float]:
    """Points of ``P`` inside the closed surface ``V, F`` and the deepest one's depth.

    Generalized winding numbers (libigl: > 0.5 is inside) on the points in the
    surface's bounding box: the fast hierarchical approximation (Barill et al.
    2018) first, then the exact sum over every triangle (``winding_number``)
    wherever the approximation lies within 0.25 of the threshold (points near
    the surface); and the exact distance to the surface of those inside.
    Independent of the contact solve's own tests (its grid, `Obstacle`, and its
    ray-crossing winding numbers, `musclewrap.mesh.WindingGrid`).
    """
    return inside_depths([P], V, F)[0]


def inside_depths(
    Ps: list[FloatArray], V: FloatArray, F: IntArray, *, cache: Path | None = None
) -> list[tuple[int, float]]:
    """`inside_depth` of several point sets against one surface, the surface's trees built once.

    libigl builds its hierarchy of ``V, F`` on every call, which costs more than the
    queries of a muscle's points against a bone: the sets go in one call. Each
    point's winding number and distance do not depend on the other points queried.
    ``cache``: a folder where the same arrays' answers, found before, are read back
    (`musclewrap._cache.cached_measure`; the check's measures at rest, at every start).
    """
    if not Ps:
        return []
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    Ps = [np.ascontiguousarray(P, dtype=np.float64) for P in Ps]
    got = cached_measure(
        cache, "inside-1", [*Ps, V, F],
        lambda: dict(zip(("n", "depth"), np.array(_inside_depths(Ps, V, F)).T, strict=True)),
    )  # fmt: skip
    return [(int(n), float(d)) for n, d in zip(got["n"], got["depth"], strict=True)]


def _inside_depths(Ps: list[FloatArray], V: FloatArray, F: IntArray) -> list[tuple[int, float]]:
    import igl

    lo, hi = V.min(0), V.max(0)
    idx = [np.flatnonzero(((P >= lo) & (P <= hi)).all(axis=1)) for P in Ps]
    Q = np.vstack([np.asarray(P, dtype=np.float64)[i] for P, i in zip(Ps, idx, strict=True)])
    if not len(Q):
        return [(0, 0.0) for _ in Ps]
    Q = np.ascontiguousarray(Q)
    w = igl.fast_winding_number(V, F, Q)
    close = np.flatnonzero(np.abs(w - 0.5) < 0.25)
    if len(close):
        w[close] = igl.winding_number(V, F, np.ascontiguousarray(Q[close]))
    inside = w > 0.5
    d = np.zeros(len(Q))
    if inside.any():
        sq, _, _ = igl.point_mesh_squared_distance(np.ascontiguousarray(Q[inside]), V, F)
        d[inside] = np.sqrt(sq)
    out, o = [], 0
    for i in idx:
        here = slice(o, o + len(i))
        o += len(i)
        n = int(inside[here].sum())
        out.append((n, float(d[here][inside[here]].max()) if n else 0.0))
    return out


def muscle_overlaps(
    meshes: dict[str, tuple[FloatArray, IntArray]], *, cache: Path | None = None
) -> dict[str, tuple[int, float, str]]:
    """Per muscle, its vertices inside the others (`inside_depth` against each).

    Returns, per name of ``meshes`` (name -> closed surface ``V, F``): how many of its
    vertices lie inside another surface (a vertex inside two counts twice), the
    deepest one's distance to that surface, and the name of the surface it is in
    ("" and 0 when none is). ``cache``: as `inside_depths`'s.
    """
    # against each surface, the others' vertices in one query (its trees built once)
    against = {
        b: dict(
            zip(
                others,
                inside_depths([meshes[a][0] for a in others], *meshes[b], cache=cache),
                strict=True,
            )
        )  # fmt: skip
        for b in meshes
        for others in [[a for a in meshes if a != b]]
    }
    out = {}
    for a in meshes:
        found = {b: against[b][a] for b in meshes if b != a}
        hit = {b: d for b, (c, d) in found.items() if c}
        other = max(hit, key=lambda b: hit[b], default="")
        out[a] = (sum(c for c, _ in found.values()), hit.get(other, 0.0), other)
    return out


def verify_run(scene: Scene, outdir: Path, frames: str | None = None) -> list[dict[str, Any]]:
    """Check the meshes a run wrote against the scene's bones at full resolution.

    Reads every ``<muscle>/<muscle>_<frame>.vtp`` of ``outdir`` back, places
    each bone (as read from its file, not the decimated display copy) in the
    output frame of that frame, and measures exactly (`inside_depth`) how deep
    muscle vertices lie inside bones and bone vertices inside muscles, and the
    relative volume error of the file against the muscle's input mesh.

    Parameters
    ----------
    scene : Scene
        The scene that was run.
    outdir : pathlib.Path
        Its output folder (one motion).
    frames : str, optional
        The ``--frames`` the run was given.

    Returns
    -------
    list of dict
        Per frame and muscle: ``frame, muscle, muscle_in_bone, bone_in_muscle``
        (deepest, mesh units, 0 if none), ``muscle_in_bone_vertices``,
        ``bone_in_muscle_vertices``, ``relative_volume_error`` (of the file,
        against the muscle's mesh as the run cleaned it); and against the other
        muscles of the frame (read back the same way): ``muscle_in_muscle`` (its
        deepest vertex inside any other muscle), ``muscle_in_muscle_vertices`` (how
        many of its vertices are inside another) and ``muscle_in_muscle_other`` (the
        muscle the deepest one is in, "" if none).
    """
    bones = {}
    for b in scene.bones:
        V, F, _ = tidy_mesh(*read_mesh(b.mesh))
        bones[b.name] = (V * np.asarray(b.scale), F, b.body)  # (a model's mesh: scaled)
    drive = drive_scene(scene, frames, {n: V.mean(axis=0) for n, (V, _, _) in bones.items()})
    rest_volume = {}
    cleaned = {}
    for m in scene.muscles:
        # the mesh as the run cleaned it (a repair changes its volume by up to 1e-6), read
        # again here: the contact's push-out at rest keeps the volume exactly; placed as
        # the run places it (a registration scales it: the volume by the scale cubed)
        V, F = read_mesh(m.mesh)
        V, F, _ = clean_mesh(V, F, source=str(m.mesh), repair=m.repair)
        rest_volume[m.name] = abs(volume(V, F) * np.linalg.det(drive.to_body[m.name][:3, :3]))
        cleaned[m.name] = (apply_transform(drive.to_body[m.name], V), F)
    if any(b.fit for b in scene.bones):
        # a bone fitted to its muscles at rest, as the run fits it
        fits = fit_bones(scene, drive, cleaned, None, lambda _: None, [])
        for n, f in fits.items():
            V, F, body = bones[n]
            Vb = apply_transform(drive.to_body[n], V)
            back = np.linalg.inv(drive.to_body[n])
            bones[n] = (apply_transform(back, Vb + f.move(Vb)), F, body)
    rows = []
    for k, frame in enumerate(drive.frames):
        placed = {
            n: (apply_transform(drive.to_output[body][k], apply_transform(drive.to_body[n], V)), F)
            for n, (V, F, body) in bones.items()
        }
        written = {}
        for m in scene.muscles:
            path = Path(outdir) / m.name / f"{m.name}_{frame:04d}.vtp"
            if path.is_file():
                written[m.name] = read_mesh(path)
        overlaps = muscle_overlaps(written)
        for m in scene.muscles:
            if m.name not in written:
                continue
            P, PF = written[m.name]
            mib = [inside_depth(P, BV, BF) for BV, BF in placed.values()]
            bim = [inside_depth(BV, P, PF) for BV, _ in placed.values()]
            n_in, deepest, other = overlaps[m.name]
            rows.append(
                {
                    "frame": frame,
                    "muscle": m.name,
                    "muscle_in_bone": max((d for _, d in mib), default=0.0),
                    "muscle_in_bone_vertices": sum(c for c, _ in mib),
                    "bone_in_muscle": max((d for _, d in bim), default=0.0),
                    "bone_in_muscle_vertices": sum(c for c, _ in bim),
                    "relative_volume_error": volume(P, PF) / rest_volume[m.name] - 1.0,
                    "muscle_in_muscle": deepest,
                    "muscle_in_muscle_vertices": n_in,
                    "muscle_in_muscle_other": other,
                }
            )
    return rows

"""Muscles of one pose solved together: each against its bones, then against each other.

Each muscle is solved on its own (`Deformer.deform` without the fine finish); then,
in rounds, every muscle's vertices inside another (`musclewrap.contact.overlaps`)
are taken out by a share of their depth (`defaults.muscle_share`, half: the other
muscle's vertices inside it take the other half, so the surfaces meet between where
they were), through the faces that face it at rest, by one least-energy step of its
cage with its bones' conditions (`Deformer.contact_round`). The rounds are Jacobi
rounds: every muscle's step is computed from the same snapshot of all of them, and
the muscles go in the order of their names, so the result does not depend on the
order they are given in. Then each muscle's bone finish (`Deformer.settle`) and,
exact, the deepest vertex still inside another.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from ..constants import defaults, tol
from ..contact import (
    Near,
    Overlap,
    facing_faces,
    longest_pushes,
    nudge,
    overlap_depths,
    overlaps,
    triangle_pushes,
)
from ..mesh import WindingGrid
from ._muscle import Deformer
from ._result import DeformationResult

__all__ = ["deform_together", "facing_at_rest", "meet"]


def _apply(T: FloatArray | None, P: FloatArray) -> FloatArray:
    return P if T is None else P @ T[:3, :3].T + T[:3, 3]


def _cat(found: Sequence[Overlap], field: str, shape: tuple[int, ...]) -> npt.NDArray[Any]:
    """One field of several overlaps, end to end (empty of ``shape`` where there are none)."""
    if not found:
        return np.zeros(shape, dtype=np.int64 if field in ("rows", "face") else np.float64)
    return np.concatenate([getattr(o, field) for o in found])


def _deepest(found: Sequence[Overlap]) -> float:
    """The deepest of several overlaps' vertices (0 where there are none)."""
    return max((float(o.depth.max()) for o in found), default=0.0)


def _nudge(
    d: Deformer,
    V: FloatArray,
    S: FloatArray,
    rows: IntArray,
    need: FloatArray,
    out: FloatArray,
    faces: IntArray,
    at: FloatArray,
    give: FloatArray,
    back: FloatArray,
) -> FloatArray | None:
    """A muscle's fine vertices out of the others by ``need`` along ``out``, its surface giving way.

    ``faces, at, give, back``: where another muscle's vertex stands inside this one,
    the point ``at`` of its triangle ``faces`` (``S``: this muscle's positions in the
    frame of ``at``) moves by ``give`` along ``back`` (`musclewrap.contact.triangle_pushes`).
    A vertex pushed twice takes the longer push. `musclewrap.contact.nudge` spreads
    them and keeps the volume.
    """
    mu = d.muscle
    slack = tol.contact * d._fine_edge
    push, size = np.zeros((len(V), 3)), np.zeros(len(V))
    verts = np.concatenate([rows, mu.F[faces].ravel()])
    disp = np.vstack(
        [
            (need + slack)[:, None] * out,
            triangle_pushes(at, S[mu.F[faces]], (give + slack)[:, None] * back),
        ]
    )
    if not len(verts):
        return None
    longest_pushes(push, size, verts, disp)
    hit = np.unique(verts)
    return nudge(
        V, mu.F, mu.adjacency, hit, push[hit], volume_target=mu.volume_rest, edge=d._fine_edge
    )


def facing_at_rest(
    deformers: Mapping[str, Deformer],
    rest_frames: Mapping[str, FloatArray] | None = None,
    reach: float | None = None,
) -> dict[tuple[str, str], IntArray]:
    """For every ordered pair, the faces of the second that face the first at rest.

    ``rest_frames[name]``: the transform from the muscle's frame into a common one
    at rest (default: they share one). ``reach`` (mesh units): default
    ``defaults.muscle_facing_reach``.
    """
    reach = defaults.muscle_facing_reach if reach is None else reach
    names = sorted(deformers)
    rest = {
        n: (
            _apply(None if rest_frames is None else rest_frames[n], deformers[n].muscle.V),
            deformers[n].muscle.F,
        )
        for n in names
    }
    grids = {n: WindingGrid(*rest[n]) for n in names}
    return {
        (a, b): facing_faces(*rest[a], *rest[b], reach, grids[a])
        for a in names
        for b in names
        if a != b
    }


def meet(
    deformers: Mapping[str, Deformer],
    results: Mapping[str, DeformationResult],
    lines: Mapping[str, Mapping[str, npt.ArrayLike]],
    *,
    frames: Mapping[str, FloatArray] | None = None,
    reference_points: Mapping[str, npt.ArrayLike | None] | None = None,
    obstacles: Mapping[str, Sequence[Any] | None] | None = None,
    margin: float = 0.0,
    sides: Mapping[str, Any] | None = None,
    facing: Mapping[tuple[str, str], IntArray] | None = None,
    pairs: Sequence[tuple[str, str]] | None = None,
) -> dict[str, DeformationResult]:
    """Muscles solved on their own (``finish=False``) taken out of each other, then finished.

    ``frames[name]``: the transform from the muscle's frame into one common to
    all in this pose (default: they share one). ``obstacles``, ``sides``: per
    muscle, as `Deformer.deform` takes them. ``facing``: `facing_at_rest`
    (computed here when None). ``pairs``: the pairs of muscles kept apart
    (default: every pair); the exact depth reported is over every pair. Returns each muscle's finished result with
    ``muscle_overlap`` and ``muscle_rounds``.
    """
    names = sorted(deformers)
    frames = frames or {}
    refs = reference_points or {}
    obstacles = obstacles or {}
    sides = sides or {}
    if facing is None:
        facing = facing_at_rest(deformers)
    edge = {n: float(deformers[n]._fine_edge) for n in names}
    state = {n: (results[n].cage, results[n].V) for n in names}
    live = [n for n in names if np.isfinite(state[n][1]).all()]
    if pairs is None:
        pairs = [(a, b) for i, a in enumerate(live) for b in live[i + 1 :]]
    else:
        pairs = sorted({tuple(sorted(p)) for p in pairs if p[0] in live and p[1] in live})
    nears: dict[str, Near] = {}
    rounds = 0
    surf = {n: (_apply(frames.get(n), state[n][1]), deformers[n].muscle.F) for n in live}
    memo: dict[Any, Any] = {}  # what stays over the rounds for the muscles that stay
    for _ in range(defaults.muscle_rounds if pairs else 0):
        found = overlaps(surf, pairs, facing, memo)
        # per muscle its deepest vertex inside another, in its mean edges
        deep = {n: _deepest(found[n]) / edge[n] for n in live}
        if max(deep.values()) <= defaults.muscle_overlap_depth:
            break  # all out, to the tolerance
        rounds += 1
        share = defaults.muscle_share
        # where another muscle's vertex stands inside this one: its surface gives the other
        # share there (a muscle held by a bone cannot take its own; and where only one
        # surface has vertices inside the other, both still move)
        given: dict[str, list[Overlap]] = {n: [] for n in live}
        for m in live:
            for o in found[m]:
                given[o.other].append(o)
        new = {}
        for n in live:
            mine = _deepest(given[n]) / edge[n]
            if max(deep[n], mine) <= defaults.muscle_overlap_depth:
                continue  # out already (to the tolerance): no step
            V = state[n][1]
            rows, need = _cat(found[n], "rows", (0,)), share * _cat(found[n], "depth", (0,))
            give = (1.0 - share) * _cat(given[n], "depth", (0,))
            faces, at = _cat(given[n], "face", (0,)), _cat(given[n], "point", (0, 3))
            # the ways out, and the other's surface's way in, in the muscle's frame
            out, back = _cat(found[n], "out", (0, 3)), -_cat(given[n], "out", (0, 3))
            if frames.get(n) is not None:
                out, back = out @ frames[n][:3, :3], back @ frames[n][:3, :3]
            if max(deep[n], mine) <= defaults.muscle_fine_depth:
                # a fraction of an edge: the fine vertices themselves (the cage cannot take
                # a few vertices out without moving their whole region)
                Vn = _nudge(deformers[n], V, surf[n][0], rows, need, out, faces, at, give, back)
                if Vn is not None:
                    new[n] = (state[n][0], Vn)
                    continue
            points = None
            if len(faces):
                Wp = deformers[n].surface_rows(at, faces, surf[n][0])
                points = (Wp, give, back)
            obs = obstacles.get(n)
            if obs and n not in nears:
                nears[n] = Near(V, obs, margin)
            new[n] = deformers[n].contact_round(
                *state[n], rows, need, out, obstacles=obs, margin=margin, sides=sides.get(n),
                near=nears.get(n), points=points,
            )  # fmt: skip
        for n, (x, V) in new.items():
            if V is not state[n][1]:  # moved: its surface anew (the others' stay, memo too)
                surf[n] = (_apply(frames.get(n), V), deformers[n].muscle.F)
        state.update(new)
    final = {
        n: deformers[n].settle(
            results[n],
            *state[n],
            lines[n],
            reference_point=refs.get(n),
            obstacles=obstacles.get(n),
            margin=margin,
            sides=sides.get(n),
        )  # fmt: skip
        for n in names
    }
    ok = [n for n in names if np.isfinite(final[n].V).all()]
    depth = overlap_depths(
        {n: (_apply(frames.get(n), final[n].V), deformers[n].muscle.F) for n in ok},
        [(a, b) for i, a in enumerate(ok) for b in ok[i + 1 :]],
    )
    return {
        n: dataclasses.replace(
            final[n],
            muscle_overlap=depth[n][1] if n in depth else float("nan"),
            muscle_rounds=rounds,
        )
        for n in names
    }


def deform_together(
    deformers: Mapping[str, Deformer],
    lines: Mapping[str, Mapping[str, npt.ArrayLike]],
    *,
    frames: Mapping[str, FloatArray] | None = None,
    reference_points: Mapping[str, npt.ArrayLike | None] | None = None,
    obstacles: Mapping[str, Sequence[Any] | None] | None = None,
    margin: float = 0.0,
    sides: Mapping[str, Any] | None = None,
    facing: Mapping[tuple[str, str], IntArray] | None = None,
    pairs: Sequence[tuple[str, str]] | None = None,
    **kw: Any,
) -> dict[str, DeformationResult]:
    """Deform several muscles for one pose together: each follows its lines, none inside another.

    Parameters
    ----------
    deformers : mapping of name to Deformer
        The muscles, bound to their rest lines.
    lines : mapping of name to lines
        Each muscle's current lines (as `Deformer.deform` takes them).
    frames : mapping of name to (4, 4) array, optional
        The transform from each muscle's frame into one common to all in this pose
        (default: they share one).
    reference_points, obstacles, sides : mappings by name, optional
        As `Deformer.deform` takes them, per muscle.
    margin : float, optional
        The bones' margin.
    facing : optional
        `facing_at_rest` (computed when None: the muscles' rest meshes must then
        share a frame).
    pairs : sequence of (str, str), optional
        The pairs kept apart (default: every pair).
    **kw
        ``method``, ``max_iterations``: passed to each solve.

    Returns
    -------
    dict of name to DeformationResult
        With ``muscle_overlap`` (exact) and ``muscle_rounds``.
    """
    refs = reference_points or {}
    obstacles = obstacles or {}
    sides = sides or {}
    results = {
        n: d.deform(
            lines[n],
            reference_point=refs.get(n),
            obstacles=obstacles.get(n),
            margin=margin,
            finish=False,
            sides=sides.get(n),
            **kw,
        )  # fmt: skip
        for n, d in deformers.items()
    }
    return meet(
        deformers, results, lines, frames=frames, reference_points=refs, obstacles=obstacles,
        margin=margin, sides=sides, facing=facing, pairs=pairs,
    )  # fmt: skip

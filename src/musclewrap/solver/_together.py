"""Muscles of one pose solved together: each against its bones, then against each other.

Each muscle is solved on its own (`Deformer.deform` without the fine finish); then,
in rounds, every muscle's vertices inside another (`musclewrap.contact.overlaps`)
are taken out by a share of their depth (`defaults.muscle_share`, half: the other
muscle's vertices inside it take the other half, so the surfaces meet between where
they were), through the faces that face it at rest, by one least-energy step of its
cage with its bones' conditions (`Deformer.contact_round`), the folds it made ironed
out (`Deformer.ironed`). The rounds are Jacobi
rounds: every muscle's step is computed from the same snapshot of all of them, and
the muscles go in the order of their names, so the result does not depend on the
order they are given in. Then each muscle's bone finish (`Deformer.settle`) and,
exact, the deepest vertex still inside another.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from ..constants import defaults
from ..contact import (
    Near,
    as_placed,
    every_pair,
    facing_pairs,
    meetings,
    overlap_depths,
    overlaps,
    push_apart,
)
from ..mesh import apply_transform
from ._deformer import Deformer
from ._group import joint_round, overlap_groups
from ._result import DeformationResult

__all__ = ["deform_together", "facing_at_rest", "meet"]


def _apply(T: FloatArray | None, P: FloatArray) -> FloatArray:
    return P if T is None else apply_transform(T, P)


def facing_at_rest(
    deformers: Mapping[str, Deformer],
    rest_frames: Mapping[str, FloatArray] | None = None,
    reach: float | None = None,
    cache: Path | None = None,
) -> dict[tuple[str, str], IntArray]:
    """For every ordered pair, the faces of the second that face the first at rest.

    ``rest_frames[name]``: the transform from the muscle's frame into a common one
    at rest (default: they share one). ``reach`` (mesh units): default
    ``defaults.muscle_facing_reach``. ``cache``: a folder where each pair's faces
    are kept between processes (`facing_pairs`).
    """
    names = sorted(deformers)
    rest = {
        n: (
            _apply(None if rest_frames is None else rest_frames[n], deformers[n].muscle.V),
            deformers[n].muscle.F,
        )
        for n in names
    }
    return facing_pairs(rest, reach, cache)


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
    together: bool | None = None,
) -> dict[str, DeformationResult]:
    """Muscles solved on their own (``finish=False``) taken out of each other, then finished.

    ``frames[name]``: the transform from the muscle's frame into one common to
    all in this pose (default: they share one). ``obstacles``, ``sides``: per
    muscle, as `Deformer.deform` takes them. ``facing``: `facing_at_rest`
    (computed here when None). ``pairs``: the pairs of muscles kept apart
    (default: every pair); the exact depth reported is over every pair.
    ``together``: muscles that overlap in a round take one step together
    (`musclewrap.solver._group.joint_round`; default ``defaults.muscle_joint``).
    Returns each muscle's finished result with ``muscle_overlap`` and ``muscle_rounds``.
    """
    names = sorted(deformers)
    frames = frames or {}
    refs = reference_points or {}
    obstacles = obstacles or {}
    sides = sides or {}
    if facing is None:
        facing = facing_at_rest(deformers)
    joint = defaults.muscle_joint if together is None else together
    rounds = _Rounds(
        deformers, results, frames, obstacles, margin, sides, facing, pairs, joint
    )  # fmt: skip
    final: dict[str, DeformationResult] = {}
    ok: list[str] = []
    for settled in range(max(1, defaults.muscle_finish_passes)):
        taken = rounds.count  # the rounds before this pass
        if settled:
            # the bones' finish pushed a muscle deep into another: the rounds again, from
            # where the finish left them (it has the last word on the bones)
            rounds.restart({n: final[n] for n in ok})
        rounds.run()
        if settled and rounds.count == taken:
            break  # no round since the last finish: it stands (again it would give the same)
        final = {
            n: deformers[n].settle(
                results[n],
                *rounds.state[n],
                lines[n],
                reference_point=refs.get(n),
                obstacles=obstacles.get(n),
                margin=margin,
                sides=sides.get(n),
            )  # fmt: skip
            for n in names
        }
        ok = [n for n in names if np.isfinite(final[n].V).all()]
        # the exact check; a surface the finish did not move is the rounds' own (and what the
        # rounds found about it is taken again)
        surf = {
            n: rounds.surf[n] if n in rounds.surf and final[n].V is rounds.state[n][1]
            else (_apply(frames.get(n), final[n].V), deformers[n].muscle.F)
            for n in ok
        }  # fmt: skip
        depth = overlap_depths(surf, every_pair(ok), rounds.memo)
        # the rounds again only for the pairs they keep apart (the others are measured only)
        kept = [p for p in rounds.pairs if p[0] in ok and p[1] in ok]
        if (
            rounds.count >= defaults.muscle_rounds
            or not kept
            or all(
                d <= defaults.muscle_finish_retry * rounds.edge[n]
                for n, (_, d) in _deepest(depth, surf, kept, rounds.memo).items()
            )
        ):
            break
    return {
        n: dataclasses.replace(
            final[n],
            muscle_overlap=depth[n][1] if n in depth else float("nan"),
            muscle_rounds=rounds.count,
        )
        for n in names
    }


class _Rounds:
    """The rounds of one pose that take muscles out of each other, and what they keep.

    ``state[name]``: each muscle's cage and fine vertices as the rounds leave them;
    ``surf[name]``: its surface in the common frame (the muscles whose solve gave
    finite positions); ``memo``: what `overlaps` keeps over the rounds for the
    surfaces that do not move; ``count``: the rounds taken, over every pass.
    """

    def __init__(
        self,
        deformers: Mapping[str, Deformer],
        results: Mapping[str, DeformationResult],
        frames: Mapping[str, FloatArray],
        obstacles: Mapping[str, Sequence[Any] | None],
        margin: float,
        sides: Mapping[str, Any],
        facing: Mapping[tuple[str, str], IntArray],
        pairs: Sequence[tuple[str, str]] | None,
        joint: bool,
    ) -> None:
        self.deformers, self.results, self.frames = deformers, results, frames
        self.obstacles, self.margin, self.sides = obstacles, margin, sides
        self.facing, self.joint = facing, joint
        names = sorted(deformers)
        self.edge = {n: float(deformers[n]._fine_edge) for n in names}
        self.state = {n: (results[n].cage, results[n].V) for n in names}
        self.live = [n for n in names if np.isfinite(self.state[n][1]).all()]
        self.pairs = every_pair(self.live, pairs)
        self.surf = {n: self._placed(n, self.state[n][1]) for n in self.live}
        self.memo: dict[Any, Any] = {}  # what stays over the rounds for the muscles that stay
        self.nears: dict[str, Near] = {}
        self.count = 0

    def _placed(self, n: str, V: FloatArray) -> tuple[FloatArray, IntArray]:
        """Muscle ``n``'s surface at ``V`` in the common frame."""
        return _apply(self.frames.get(n), V), self.deformers[n].muscle.F

    def restart(self, final: Mapping[str, DeformationResult]) -> None:
        """Go on from the finished results ``final`` (the muscles the finish left finite)."""
        self.state.update({n: (r.cage, r.V) for n, r in final.items()})
        self.surf.update({n: self._placed(n, r.V) for n, r in final.items()})

    def run(self) -> None:
        """Rounds until every kept pair is apart (to the tolerance), or the rounds' cap.

        At the cap the rounds go back to the positions they found least deep (the
        deepest vertex of any muscle in another, in its muscle's mean edges), where
        rounds that stall can end deeper than they were (the 19-muscle leg stepped
        together at the deep squat's frame 244: 8.9 mm, BENCHMARKS.md).
        """
        best: tuple[float, dict[str, Any], dict[str, Any]] | None = None
        for _ in range(defaults.muscle_rounds - self.count if self.pairs else 0):
            deepest, found, met, worst = self._deepest()
            if deepest <= defaults.muscle_overlap_depth:
                break  # all out, to the tolerance
            if best is None or deepest < best[0]:
                best = (deepest, dict(self.state), dict(self.surf))
            self.count += 1
            new = self._round(found, met, worst)
            for n, (_, V) in new.items():
                if V is not self.state[n][1]:  # moved: its surface anew (the others stay)
                    self.surf[n] = self._placed(n, V)
            self.state.update(new)
        else:
            if best is not None and self._deepest()[0] > best[0]:
                self.state, self.surf = best[1], best[2]

    def _deepest(self) -> tuple[float, Any, Any, dict[str, float]]:
        """The muscles' overlaps now: the deepest (mean edges), what was found, each one's."""
        # each muscle's side: its vertices inside others go out by its share, and where
        # another's vertex stands inside it, its surface gives the other share (a muscle
        # held by a bone cannot take its own; where only one surface has vertices inside
        # the other, both still move)
        found = overlaps(self.surf, self.pairs, self.facing, self.memo)
        met = meetings(found, defaults.muscle_share)
        # per muscle the deepest of its vertices in another or another's in it, in its edges
        worst = {n: max(m.depth, m.given) / self.edge[n] for n, m in met.items()}
        return max(worst.values()), found, met, worst

    def _round(
        self, found: Any, met: Mapping[str, Any], worst: Mapping[str, float]
    ) -> dict[str, tuple[FloatArray, FloatArray]]:
        """One round's new cage and vertices of each muscle that moves."""
        new = {}
        cage = []  # the muscles that take a step of their cage this round
        for n in self.live:
            d = self.deformers[n]
            if worst[n] <= defaults.muscle_overlap_depth:
                continue  # out already (to the tolerance): no step
            # a fraction of an edge: the fine vertices themselves (the cage cannot take a few
            # vertices out without moving their whole region); deeper, to a few edges, a plate
            plate = defaults.muscle_fine_plate and (
                defaults.muscle_fine_depth < worst[n] <= defaults.muscle_plate_depth
            )
            if worst[n] <= defaults.muscle_fine_depth or plate:
                m = met[n].rotated(self.frames.get(n))  # the ways out in the muscle's frame
                Vn = push_apart(
                    self.state[n][1], d.muscle.F, d.muscle.adjacency, m, self.surf[n][0],
                    volume_target=d.muscle.volume_rest, edge=d._fine_edge,
                    shape_rest=d.muscle.umbrella_rest_lengths, umbrella=d.muscle.umbrella,
                    plate=plate,
                )  # fmt: skip
                if Vn is not None:
                    new[n] = (self.state[n][0], Vn)
                    continue
            cage.append(n)
            obs = self.obstacles.get(n)
            if obs and n not in self.nears:
                # the pose's bounds where its solve kept them (they hold wherever the vertices
                # have moved since)
                pose = self.results[n].pose
                self.nears[n] = (
                    Near(self.state[n][1], obs, self.margin) if pose is None else pose.near
                )
        groups = overlap_groups(cage, found) if self.joint else [[n] for n in cage]
        far = defaults.muscle_step_reach  # each step held whole, not only near the contact
        for group in groups:
            if len(group) > 1:
                # overlapping each other: one step together (an overlap one condition on both),
                # not a step each with its share
                new.update(
                    joint_round(
                        self.deformers, self.state, self.surf, found, group,
                        frames=self.frames,
                        obstacles={n: as_placed(self.obstacles.get(n)) for n in group},
                        margin=self.margin, sides=self.sides, nears=self.nears, far=far,
                    )
                )  # fmt: skip
                continue
            n = group[0]
            d, m = self.deformers[n], met[n].rotated(self.frames.get(n))
            points = None
            if len(m.faces):
                points = (d.surface_rows(m.at, m.faces, self.surf[n][0]), m.give, m.back)
            new[n] = d.contact_round(
                *self.state[n], m.rows, m.need, m.out, obstacles=self.obstacles.get(n),
                margin=self.margin, sides=self.sides.get(n), near=self.nears.get(n),
                points=points, far=far,
            )  # fmt: skip
        for n in cage:
            if n in new:
                # the folds a deep overlap's cage step made, ironed out as the bones' steps'
                x, V = new[n]
                new[n] = (x, self.deformers[n].ironed(
                    self.state[n][1], V, self.obstacles.get(n), self.margin,
                    self.nears.get(n), self.sides.get(n),
                ))  # fmt: skip
        return new


def _deepest(
    depth: dict[str, tuple[int, float]],
    surfaces: Mapping[str, tuple[FloatArray, IntArray]],
    kept: list[tuple[str, str]],
    memo: dict[Any, Any],
) -> dict[str, tuple[int, float]]:
    """``depth`` (over every pair of ``surfaces``) restricted to the pairs ``kept`` apart.

    The same where every pair is kept (the default); else measured again over those.
    """
    if kept == every_pair(list(surfaces)):
        return depth
    return overlap_depths(surfaces, kept, memo)


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
    together: bool | None = None,
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
    together : bool, optional
        Muscles that overlap in a round take one step together (default
        ``defaults.muscle_joint``: a step each with its share).
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
        margin=margin, sides=sides, facing=facing, pairs=pairs, together=together,
    )  # fmt: skip

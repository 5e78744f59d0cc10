"""The contact steps of one muscle's solve: its cage moved off the bones and other muscles.

Mixed into `Deformer` (`ContactSteps`): the cage's steps that take the fine vertices out
of the bones after the solve (`_cage_contact`, each step a least-energy move of the cage
ended on the exact fine volume, `_cage_step`; the folds they make ironed out,
`_unfolded`), the bones' vertices standing in the muscle as conditions on its triangles
(`_bone_points`), one round against other muscles
(`contact_round`, what `musclewrap.solver.meet` takes each round) and the fine finish
(`settle`, `musclewrap.contact.push_out`). What they measure and move with lives in
`musclewrap.contact`; this is the one place in the solver that steps the cage for it.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from ..constants import defaults, tol
from ..contact import (
    ContactReport,
    Inside,
    Near,
    Obstacle,
    Placed,
    SideReference,
    as_placed,
    bone_vertices_inside,
    contact_candidates,
    push_out,
    unfold,
)
from ..coordinates import rows_dot
from ..mesh import (
    barycentric,
    cubic_root_near,
    mean_rows,
    volume_cubic,
    volume_gradient,
)
from ._result import DeformationResult
from ._step import cage_push, held_changed

__all__ = ["ContactSteps"]


class ContactSteps:
    """The contact steps of `Deformer`.

    A mixin: it reads the deformer's muscle, its ``H^-1``, groups and fine edge, and
    its `Deformer._targets` and `Deformer._result`.
    """

    def contact_round(
        self,
        x: FloatArray,
        V: FloatArray,
        rows: IntArray,
        need: FloatArray,
        out: FloatArray,
        *,
        obstacles: Sequence[Placed | Obstacle] | None = None,
        margin: float = 0.0,
        sides: SideReference | None = None,
        near: Near | None = None,
        points: tuple[FloatArray, FloatArray, FloatArray] | None = None,
        far: float | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """One cage step that moves fine vertices ``rows`` by ``need`` along ``out``, bones kept.

        The conditions ``out_i . (W_i dx) >= need_i`` (``out`` unit vectors in the
        muscle's frame; a vertex may come more than once) join the obstacles' own
        (`musclewrap.contact.contact_candidates`, with ``sides``) in one least-energy
        step of the cage (`cage_push`), ended on the exact fine volume: what muscles
        pressed against each other take each round (`musclewrap.contact.overlaps`).
        Returns the new cage and fine positions (the same arrays where nothing moved).
        ``near``: the obstacles' `Near` from an earlier position of this pose's rounds
        (its bounds hold wherever the vertices have moved since). ``points``: ``(Wp,
        need, out)``, conditions on points of the surface other than its vertices
        (rows of coordinates ``Wp``, a triangle's rows weighted barycentrically):
        where another muscle's vertex stands inside this one, its surface gives way.
        ``far``: no fine vertex moves further than this many times the deepest need
        (`_end_step`; None: only those near the contact are held).
        """
        edge = self._fine_edge
        slack = tol.contact * edge
        idx, gap, N = rows, slack - np.asarray(need, dtype=np.float64), out
        if obstacles:
            placed = as_placed(obstacles)
            near = Near(V, placed, margin) if near is None else near
            bi, bg, bn = contact_candidates(
                V, placed, margin, defaults.contact_band * edge, near, sides
            )
            idx, gap, N = np.concatenate([idx, bi]), np.concatenate([gap, bg]), np.vstack([N, bn])
        extra = None
        if points is not None and len(points[0]):
            extra = (points[0], slack - np.asarray(points[1], dtype=np.float64), points[2])
        if not len(idx) and extra is None:
            return x, V
        idx = np.asarray(idx, dtype=np.int64)
        tried: list[FloatArray] = []
        step = self._cage_step(x, V, idx, gap, N, slack, extra, far=far, tried=tried)
        held = None
        for _ in range(defaults.contact_round_held if step is not None and obstacles else 0):
            # what the step put into a bone, held (the deepest condition of each cage vertex
            # alone took its place), and the step again from where it started
            grown = self._stepped_in(
                V, step[1], tried[-1], placed, margin, near, sides, bi, bg, held
            )
            if grown is None or not held_changed(held, grown, self._dominant):
                # none put in, or held as the last try held them: the same step again
                break
            held = grown
            again = self._cage_step(
                x, V, idx, gap, N, slack, extra, far=far, held=held, tried=tried
            )  # fmt: skip
            if again is None:
                break
            step = again
        return (x, V) if step is None else step

    def _stepped_in(
        self,
        V: FloatArray,
        P: FloatArray,
        dx: FloatArray,
        placed: Sequence[Placed],
        margin: float,
        near: Near,
        sides: SideReference | None,
        rows: IntArray,
        gaps: FloatArray,
        held: tuple[IntArray, FloatArray, FloatArray, FloatArray] | None = None,
    ) -> tuple[IntArray, FloatArray, FloatArray, FloatArray] | None:
        """The vertices a trial step from ``V`` to ``P`` put into a bone, as conditions at ``V``.

        Those more than ``defaults.contact_cage_depth`` mean edges too near a bone at
        ``P`` and nearer than at ``V`` by as much (``rows``, ``gaps``: the bones'
        candidates at ``V``; a vertex not among them was at least their band away).
        Each condition linearised at ``P`` and taken back to ``V``: its gap there less
        what the trial's linear step ``dx`` (`cage_push`'s, before the volume is
        restored along ``-H^-1 g``: that part, a swelling of the whole muscle, comes
        again with the next try) moved it along the bone's way out. Returns ``(rows, gap, N,
        rank)`` for `cage_push`'s ``held`` (``rank``: the gap at ``P``), after the
        conditions ``held`` of the tries before; None where the step put none in (a
        step held in one place can swing the surface into a bone further on: the next
        try holds that too, ``defaults.contact_round_held`` tries at most).
        """
        deep = defaults.contact_cage_depth * self._fine_edge
        pi, pg, pn = contact_candidates(P, placed, margin, 0.0, near, sides)
        if not len(pi) or not (pg < -deep).any():
            return None
        before = np.full(len(V), defaults.contact_band * self._fine_edge)
        np.minimum.at(before, rows, gaps)
        take = (pg < -deep) & (pg < before[pi] - deep)
        if not take.any():
            return None
        pi, pg, pn = pi[take], pg[take], pn[take]
        moved = np.einsum("ij,ij->i", pn, self.muscle.W[pi] @ dx)
        new = (pi, pg - moved, pn, pg)
        if held is None:
            return new
        return tuple(np.concatenate([a, b]) for a, b in zip(held, new, strict=True))  # type: ignore[return-value]

    def ironed(
        self,
        V0: FloatArray,
        V: FloatArray,
        obstacles: Sequence[Placed | Obstacle] | None = None,
        margin: float = 0.0,
        near: Near | None = None,
        sides: SideReference | None = None,
    ) -> FloatArray:
        """``V`` (a round's cage step from ``V0``) with the folds it made ironed out (`_unfolded`).

        What `musclewrap.solver.meet` does to each muscle's cage step in a round: a deep
        overlap's step folds the fine vertices near the cage's surface as the bones'
        steps do (the 19-muscle leg's pectineus at the deep squat's bottom: 0.15 -> 1.22
        mean edges of shape change in its first round, BENCHMARKS.md). The vertices near
        the ``obstacles`` (``near``: their bounds, from this pose) stay where the step put
        them, but for the folds themselves.
        """
        if V is V0:
            return V
        placed = as_placed(obstacles) if obstacles else []
        if placed and near is None:
            near = Near(V0, placed, margin)
        return self._unfolded(V0, V, placed, margin, near, sides)

    def _unfolded(
        self,
        V0: FloatArray,
        V: FloatArray,
        placed: Sequence[Placed],
        margin: float,
        near: Near | None,
        sides: SideReference | None,
    ) -> FloatArray:
        """``V`` (the cage steps' result from ``V0``) with the folds they made ironed out.

        A cage step moves the cage's vertices near the contact, and the fine vertices
        near the cage's surface, where mean value coordinates are nearly linear on its
        triangles, fold along its edges (the gluteus maximus past 100 deg of hip
        flexion, 2-37 mm from any bone: BENCHMARKS.md). `musclewrap.contact.unfold`,
        away from the vertices within ``defaults.fold_held`` mean edges of a bone's
        margin (where the steps had to put them) that are not folds themselves (a fold
        on the bone is ironed with the rest; the finish puts it back on the bone).
        """
        mu = self.muscle
        shape = mu.shape_change(V)
        if not shape.max() > defaults.fold_shape:
            return V  # no fold (the common case: nothing more is measured)
        keep = np.zeros(len(V), dtype=bool)
        if placed:
            assert near is not None
            reach = defaults.fold_held * self._fine_edge
            keep[contact_candidates(V, placed, margin, reach, near, sides)[0]] = True
        return unfold(
            V0, V, mu.F, mu.umbrella, mu.shape_change(V0), shape, keep,
            volume_target=mu.volume_rest,
        )  # fmt: skip

    def settle(
        self,
        result: DeformationResult,
        x: FloatArray,
        V: FloatArray,
        current_lines: Mapping[str, npt.ArrayLike],
        *,
        reference_point: npt.ArrayLike | None = None,
        obstacles: Sequence[Placed | Obstacle] | None = None,
        margin: float = 0.0,
        sides: SideReference | None = None,
    ) -> DeformationResult:
        """The result of a pose solved with ``finish=False`` and moved since (``x, V``), finished.

        The obstacles' fine finish (`musclewrap.contact.push_out`) on ``V``, then the
        result as `deform` gives it (fit and energy of the cage ``x``, the contact's
        report; the solve's iterations, history and reason kept).
        """
        t0 = time.perf_counter()
        pose = result.pose
        with np.errstate(all="ignore"):
            if pose is None:
                cur, s_cur, d_L = self._targets(current_lines, reference_point)
            else:
                cur, s_cur, d_L = pose.targets
            ok, reason, contact = result.converged, result.reason, None
            if obstacles and np.isfinite(V).all():
                placed = as_placed(obstacles)
                # the pose's bounds (they hold wherever the vertices have moved since), and
                # the bones inside the muscle where it has not moved since they were found
                near = Near(V, placed, margin) if pose is None else pose.near
                inside = None if pose is None or pose.at is not V else pose.inside
                V, contact, ok, reason = self._finish(
                    V, placed, margin, near, sides, result.penetration_depth_before, ok, reason,
                    inside,
                )  # fmt: skip
            res = self._result(
                x, V, result.iterations, ok, reason, list(result.history), cur, d_L, s_cur,
                result.method, t0, contact,
            )  # fmt: skip
        return dataclasses.replace(res, seconds=result.seconds + res.seconds)

    def _finish(
        self,
        V: FloatArray,
        placed: Sequence[Placed],
        margin: float,
        near: Near,
        sides: SideReference | None,
        before: float,
        ok: bool,
        reason: str,
        inside: list[Inside] | None = None,
    ) -> tuple[FloatArray, ContactReport, bool, str]:
        """The obstacles' fine finish (`push_out`) on ``V``: positions, report, verdict, reason."""
        V, contact = push_out(
            V,
            self.muscle.F,
            placed,
            volume_target=self.muscle.volume_rest,
            margin=margin,
            A=self.muscle.adjacency,
            edge=self._fine_edge,
            near=near,
            bone_vertices="near",
            faces=self.muscle.vertex_faces,
            sides=sides,
            inside=inside,
        )
        contact = dataclasses.replace(contact, depth_before=max(before, contact.depth_before))
        if not contact.ok:
            reason = contact.reason if ok else f"{reason}; {contact.reason}"
            ok = False
        return V, contact, ok, reason

    def _cage_contact(
        self,
        x: FloatArray,
        V: FloatArray,
        placed: Sequence[Placed],
        margin: float,
        near: Near,
        sides: SideReference | None = None,
    ) -> tuple[FloatArray, FloatArray, float, list[Inside] | None]:
        """Move the cage so that the fine vertices leave the obstacles (`cage_push`).

        Repeated on the new positions while a vertex is more than
        ``defaults.contact_cage_depth`` mean fine edges too near; then once with
        the obstacles' vertices standing in the muscle (`_bone_points`); each step
        ends on the exact fine volume (a cubic along ``-H^-1 g``). The folds the
        steps made away from the bones are ironed out (`_unfolded`). What remains
        is left to the fine finish (`push_out`). Returns the cage, the fine
        positions, the deepest vertex inside an obstacle before the first step,
        and the obstacles' vertices inside the muscle at the returned positions
        where they were looked for there (None otherwise).
        """
        edge = self._fine_edge
        slack = tol.contact * edge
        band = defaults.contact_band * edge
        before = 0.0
        if near.deepest() < edge and (
            sides is None
            or not any(
                len(sides.approaching(b, V, margin + band, 0.25 * band)) for b in range(len(placed))
            )
        ):
            # no vertex can be a mean edge too near (the grid's bounds), nor have come
            # through a thin bone (past it, not near it, yet on the wrong side): nothing
            # for the cage
            return x, V, before, None
        # the deepest vertex inside an obstacle as the solve left it (exact)
        before = max(
            pl.obstacle.measure(pl.to_obstacle(V[near.within(b, V, -near.allowed[b])]))[1]
            for b, pl in enumerate(placed)
        )
        V_solved = V
        inside_pass = 0
        points = None
        found: tuple[FloatArray, list[Inside]] | None = None  # positions, bones inside there
        for step_no in range(defaults.contact_cage_steps):
            idx, gap, N = contact_candidates(V, placed, margin, band, near, sides)
            deep = len(idx) and gap.min() < -defaults.contact_cage_depth * edge
            if not deep and inside_pass < defaults.contact_cage_bone_passes:
                # the muscle's vertices are out (to half an edge): the bones' vertices that
                # stand in it (a spur between its vertices) as conditions on its triangles,
                # for the cage to move the region round them, not the finish to tent it
                inside_pass += 1
                points, inside = self._bone_points(V, placed, margin, near, edge)
                found = (V, inside)
            if not deep and points is None:
                break
            # the later steps meet a stiff condition as far as a supple one (the first ones
            # spread a deep push over the cage)
            own = step_no >= defaults.contact_stiff_from
            step = self._cage_step(x, V, idx, gap, N, slack, points, own=own)
            points = None
            if step is None:
                break
            x, V = step
        if V is not V_solved:
            V = self._unfolded(V_solved, V, placed, margin, near, sides)
        # the finish need not look again where nothing moved since
        return x, V, before, (found[1] if found is not None and found[0] is V else None)

    def _cage_step(
        self,
        x: FloatArray,
        V: FloatArray,
        idx: IntArray,
        gap: FloatArray,
        N: FloatArray,
        slack: float,
        points: tuple[FloatArray, FloatArray, FloatArray] | None = None,
        own: bool = False,
        far: float | None = None,
        held: tuple[IntArray, FloatArray, FloatArray, FloatArray] | None = None,
        tried: list[FloatArray] | None = None,
    ) -> tuple[FloatArray, FloatArray] | None:
        """One contact step of the cage (`cage_push`), ended on the exact fine volume.

        ``own``: each condition softened by its own diagonal (`cage_push`); ``far``: as
        `_end_step`'s; ``held``: `cage_push`'s; ``tried``: `cage_push`'s step appended
        to it. None where it moves nothing or the volume cannot be restored along
        ``-H^-1 g``.
        """
        mu = self.muscle
        # the volume's direction at this step's own cage: one kept through a pose's steps,
        # or the solve's last one for its first, creased the LHDL squat's gluteus maximus
        # (BENCHMARKS.md, "What contact costs": what we tried)
        g, Hg = self._volume_direction(x)
        dx = cage_push(
            mu.W, self._Hinv, g, Hg, idx, gap, N, self._dominant, slack=slack, points=points,
            own=own, held=held,
        )  # fmt: skip
        if tried is not None:
            tried.append(dx)
        need = float(max(-gap.min(initial=0.0), 0.0))
        if points is not None:
            need = max(need, float(-points[1].min()))
        return self._end_step(x, V, dx, Hg, idx, need, None if points is None else points[0], far)

    def _volume_direction(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The volume's gradient in cage space at ``x`` (on the proxy) and ``H^-1`` times it."""
        mu = self.muscle
        c = mean_rows(x)
        g = mu.proxy_W_T @ volume_gradient(mu.proxy_W @ (x - c), mu.proxy_F)
        return g, self._Hinv @ g

    def _end_step(
        self,
        x: FloatArray,
        V: FloatArray,
        dx: FloatArray,
        Hg: FloatArray,
        idx: IntArray,
        need: float,
        rows: FloatArray | None = None,
        far: float | None = None,
    ) -> tuple[FloatArray, FloatArray] | None:
        """A cage step ``dx`` taken: its reach limited, ended on the exact fine volume.

        ``idx``: the fine vertices its conditions were on, ``rows``: rows of
        coordinates of the other points they were on (or None); ``need``: the
        furthest any of them had to go; ``far``: no fine vertex at all moves further
        than this many times ``need`` (None: only those near the contact are limited).
        None where it moves nothing or the volume cannot be restored along ``-H^-1 g``.
        """
        mu = self.muscle
        if not np.abs(dx).max() > 0:
            return None
        # no vertex near the contact moves much further than the deepest one must: where
        # the conditions conflict (a muscle squeezed between two bones) the least-energy
        # step can be several times longer, and the fine finish does better there
        D = rows_dot(mu.W, np.hstack([dx, Hg]))
        moves = [np.linalg.norm(D[idx, :3], axis=1).max(initial=0.0)]
        if rows is not None:
            moves.append(np.linalg.norm(rows @ dx, axis=1).max())
        longest = float(max(moves))
        reach = defaults.contact_cage_reach
        if far is not None:
            # a muscle's round: where its conditions conflict (muscles stacked between bones)
            # a step held only near the contact can swing a part of the muscle far from every
            # contact into one it had no condition on (`defaults.muscle_step_reach`)
            whole = float(np.linalg.norm(D[:, :3], axis=1).max())
            longest = max(longest, whole * reach / far)
        if need > 0 and longest > reach * need:
            scale = reach * need / longest
            dx = dx * scale
            D[:, :3] *= scale
        P = V + D[:, :3]
        cP = mean_rows(P)
        t = cubic_root_near(volume_cubic(P - cP, -D[:, 3:], mu.F), mu.volume_rest, 0.0)
        if not np.isfinite(t):
            return None
        return x + dx - t * Hg, P - t * D[:, 3:]

    def surface_rows(self, C: FloatArray, faces: IntArray, P: FloatArray) -> FloatArray:
        """Rows of coordinates of points ``C`` on the muscle's triangles ``faces`` (positions ``P``).

        Each point's triangle's rows of ``W`` weighted by its barycentric coordinates
        (clipped to the triangle): ``surface_rows(...) @ x`` moves the points with the
        cage, for conditions on points of the surface other than its vertices.
        ``C`` and ``P`` in one frame (any: barycentric coordinates do not change with it).
        """
        mu = self.muscle
        tri = mu.F[faces]
        w = np.clip(barycentric(C, P[tri]), 0.0, None)
        w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
        return np.einsum("ij,ijk->ik", w, mu.W[tri])

    def _bone_points(
        self, V: FloatArray, placed: Sequence[Placed], margin: float, near: Near, edge: float
    ) -> tuple[tuple[FloatArray, FloatArray, FloatArray] | None, list[Inside]]:
        """Conditions that take the obstacles' vertices standing in the muscle out of it.

        `musclewrap.contact.bone_vertices_inside` on the positions ``V``: each one
        deeper than the margin plus ``defaults.contact_bone_depth`` mean edges gives
        a condition on the muscle's nearest point (its triangle's vertices' rows of
        ``W``, weighted by the point's barycentric coordinates): past the obstacle's
        vertex along the way from it to the point; None where there are none. And
        what was found, per obstacle.
        """
        mu = self.muscle
        A = mu.adjacency
        deep = margin + defaults.contact_bone_depth * edge
        found = bone_vertices_inside(
            V, mu.F, placed, near, edge=edge, faces=mu.vertex_faces, deep=deep,
            adjacency=(A.indptr.astype(np.int64), A.indices.astype(np.int64)),
        )  # fmt: skip
        rows, gaps, dirs = [], [], []
        for pl, f in zip(placed, found, strict=True):
            keep = f.depth > deep
            if pl.allowance is not None or not keep.any():
                continue  # a kept rest overlap: the bone may stand in the muscle as it did
            B, C, fi, d = f.B[keep], f.C[keep], f.face[keep], f.depth[keep]
            rows.append(self.surface_rows(C, fi, V))
            dirs.append((B - C) / np.maximum(d, 1e-300)[:, None])
            gaps.append(-(d + margin))
        if not rows:
            return None, found
        return (np.vstack(rows), np.concatenate(gaps), np.vstack(dirs)), found

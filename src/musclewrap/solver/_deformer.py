"""The per-pose solve of one muscle bound to its rest lines (`Deformer`)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numba
import numpy as np
import numpy.typing as npt
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve

from .._typing import FloatArray, IntArray
from .._validation import as_points
from ..conditions import (
    LineError,
    RotationField,
    SampleRotations,
    check_lines,
    distinct_mask,
    minimal_rotation,
    path_rotations,
    placement_problem,
    sample_lines,
    within_reach,
)
from ..constants import defaults, tol
from ..contact import (
    Near,
    Obstacle,
    Placed,
    SideReference,
    as_placed,
    distance_outside,
    rings,
)
from ..coordinates import mean_value_coordinates, rows_dot
from ..mesh import (
    combine_pair,
    cubic_root_near,
    mean_edge_length,
    mean_rows,
    mean_thickness,
    volume,
    volume_cubic,
    volume_cubic_pair,
    volume_gradient,
    volume_hessian_reduced,
)
from ._contact import ContactSteps
from ._paper import PaperSteps
from ._prepared import PreparedMuscle
from ._proxy import PLAIN_CONVERGED, PLAIN_NO_ROOT, mat3, plain_iterations, stationary
from ._result import DeformationResult, PoseContact, Solved

__all__ = ["METHODS", "Deformer"]

METHODS = ("sqp", "exact", "paper")


@numba.njit(cache=True)
def _point_polyline_distance(Q: FloatArray, P: FloatArray) -> FloatArray:  # pragma: no cover
    """Distance from each point of ``Q`` to the poly-line ``P`` (segments without zero length)."""
    out = np.empty(Q.shape[0])
    for q in range(Q.shape[0]):
        best = np.inf
        for s in range(P.shape[0] - 1):
            ab0, ab1, ab2 = P[s + 1, 0] - P[s, 0], P[s + 1, 1] - P[s, 1], P[s + 1, 2] - P[s, 2]
            aq0, aq1, aq2 = Q[q, 0] - P[s, 0], Q[q, 1] - P[s, 1], Q[q, 2] - P[s, 2]
            t = (aq0 * ab0 + aq1 * ab1 + aq2 * ab2) / (ab0 * ab0 + ab1 * ab1 + ab2 * ab2)
            t = min(max(t, 0.0), 1.0)
            d0, d1, d2 = aq0 - t * ab0, aq1 - t * ab1, aq2 - t * ab2
            best = min(best, d0 * d0 + d1 * d1 + d2 * d2)
        out[q] = np.sqrt(best)
    return out


@numba.njit(cache=True)
def _energy_kernel(indptr, indices, data, S, x, d_L, s_cur, w2):  # noqa: ANN001, ANN202 # pragma: no cover
    # ||L x - d_L||^2 with L in CSR form (the cage Laplacian's 7 or so entries per row),
    # plus w2 ||S x - s'||^2; returns S x too (the deformed skeleton samples)
    e1 = 0.0
    for r in range(indptr.shape[0] - 1):
        a0 = a1 = a2 = 0.0
        for p in range(indptr[r], indptr[r + 1]):
            j, v = indices[p], data[p]
            a0 += v * x[j, 0]
            a1 += v * x[j, 1]
            a2 += v * x[j, 2]
        a0, a1, a2 = a0 - d_L[r, 0], a1 - d_L[r, 1], a2 - d_L[r, 2]
        e1 += a0 * a0 + a1 * a1 + a2 * a2
    Sx = np.empty((S.shape[0], 3))  # (np.zeros compiles again in every kernel: `_jit`)
    e2 = 0.0
    for r in range(S.shape[0]):
        for k in range(3):
            a = 0.0
            for j in range(S.shape[1]):
                a += S[r, j] * x[j, k]
            Sx[r, k] = a
            e2 += (a - s_cur[r, k]) ** 2
    return e1 + w2 * e2, Sx


class _Held(NamedTuple):
    """Attached vertices held to one line end (`Deformer`'s ``attached``).

    ``line``: the line's index; ``side``: 0 (its first point) or -1 (its last);
    ``offset``: the vertices' rest positions from that point; ``segment``: the line's
    end segment's unit direction at rest, away from that point; ``scale``: their
    weight over the skeleton's.
    """

    line: int
    side: int
    offset: FloatArray
    segment: FloatArray
    scale: float


def _end_segment(P: FloatArray, side: int) -> FloatArray:
    """Unit direction of a line's (distinct points ``P``) segment at its first or last end."""
    d = P[1] - P[0] if side == 0 else P[-2] - P[-1]
    return d / np.linalg.norm(d)


class Deformer(ContactSteps, PaperSteps):
    """Per-pose solver for one muscle bound to its rest action lines.

    Holds the skeleton matrix ``S`` and the inverse of
    ``A^T A = L^T L + w^2 S^T S`` (from its Cholesky factor), both fixed per
    muscle and rest pose.

    Parameters
    ----------
    muscle : Muscle
        The preparation.
    rest_lines : mapping of str to (k, 3) array_like
        Rest action lines.
    reference_point : (3,) array_like, optional
        Rest reference point.
    skeleton_weight : float, optional
        Weight of the skeleton condition.
    anchors : (k,) int array_like, optional
        Fine vertices held at their rest positions by a soft condition
        ``w_a W_a x = w_a V_a`` (rows of ``A`` like the skeleton's; weight
        ``defaults.anchor_weight * sqrt(m / k)``, feathered toward the rim of the
        anchors' patch over ``defaults.anchor_feather`` rings).
    line_reach : float or None, optional
        A line's samples beyond the first or last within this many of the muscle's
        mean thicknesses outside it are not bound (`musclewrap.conditions.within_reach`);
        None binds every sample.
    line_window : float, optional
        Half-width of each current sample's window along its line, in sample spacings
        (`Muscle.bind`); 0: the line's point.
    attached : (origin, insertion) int array_likes, optional
        Fine vertices where the muscle attaches (its fibres' areas): each one is held
        to the nearest first point (origin) or last point (insertion) of the rest
        lines, by a soft condition like the skeleton's (weight
        ``defaults.attached_weight * sqrt(m / k)``, ``k`` such vertices): in a pose it
        moves with that point and turns as the line's end segment does (the least
        rotation from where its body turned it; `_attached_targets`). Only ends the muscle
        reaches (a line whose samples there are bound, ``line_reach``): where a path
        runs on past the mesh (a tendon it does not hold) the area is not at that
        point, and is left free (`attached_held` says how many were held).

    Attributes
    ----------
    unbound : dict of str to (float, float, float)
        Per line with samples not bound: the arc-length fractions left out at its
        start and at its end, and the farthest of them from the muscle (mesh units).
    attached_held : (int, int)
        The origin's and the insertion's attached vertices held on a body (those of
        an end no bound line reaches are left free).
    """

    def __init__(
        self,
        muscle: PreparedMuscle,
        rest_lines: Mapping[str, npt.ArrayLike],
        *,
        reference_point: npt.ArrayLike | None = None,
        skeleton_weight: float = defaults.skeleton_weight,
        anchors: npt.ArrayLike | None = None,
        line_reach: float | None = defaults.line_reach,
        line_window: float = defaults.line_window,
        attached: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    ) -> None:
        if not skeleton_weight > 0:
            raise ValueError(f"skeleton_weight must be positive, got {skeleton_weight}")
        if not (np.isfinite(line_window) and line_window >= 0):
            raise ValueError(f"line_window must be 0 or positive, got {line_window}")
        self.muscle = muscle
        C, CF = muscle.cage.C, muscle.cage.CF
        rest = check_lines(rest_lines, "rest lines")
        self.rest_lines = rest
        self.spacing = mean_edge_length(C, CF) / 2
        self.sampling = sample_lines(
            rest,
            spacing=self.spacing,
            min_samples=defaults.samples_per_line,
            window=line_window * self.spacing,
        )
        self.rest_samples = self.sampling.plain.evaluate(rest, "rest lines")
        self.sample_line = self.sampling.line_index()
        self._check_near(muscle.V)
        self.unbound: dict[str, tuple[float, float, float]] = {}
        if line_reach is not None:
            if not line_reach > 0:
                raise ValueError(f"line_reach must be positive or None, got {line_reach}")
            # tendons beyond the mesh: their samples' coordinates would extrapolate the cage
            thickness = mean_thickness(muscle.V, muscle.F, muscle.volume_rest)
            self.sampling, self.unbound = within_reach(
                self.sampling,
                distance_outside(self.rest_samples, muscle.V, muscle.F),
                line_reach * thickness,
            )
            self.rest_samples = self.sampling.plain.evaluate(rest, "rest lines")
            self.sample_line = self.sampling.line_index()
        # the samples are the rest lines' points; in a pose, the lines' window means
        # (`LineSampling.halfwidths`) plus each point's offset from its rest window's mean,
        # turned with the sample: exact at rest and under a rigid motion, and free of the
        # kinks a path's point sliding past a sample gives its point
        self._plain = self.sampling.plain
        self._rest_means = self.sampling.evaluate(rest, "rest lines")
        self._sample_offset = self.rest_samples - self._rest_means
        self.S = mean_value_coordinates(self.rest_samples, C, CF)
        m, k = len(C), len(self.rest_samples)
        self.weight = skeleton_weight * np.sqrt(m / k)
        # the attachment areas, riding on their paths' end bodies: rows of S after the
        # lines' samples, scaled to their own weight (their targets: `_attached_targets`)
        self._attached, rows = self._attachments(attached, rest, m)
        if rows:
            self.S = np.vstack([self.S, *rows])
        L = muscle.L
        self.H = L.T @ L + self.weight**2 * (self.S.T @ self.S)
        # anchors: fine vertices held at their rest positions (an origin on a bone)
        self.anchors = np.zeros(0, dtype=np.int64)
        self._anchor_rhs = np.zeros((m, 3))
        self._anchor_W = np.zeros((0, m))
        self._anchor_V = np.zeros((0, 3))
        if anchors is not None and len(np.atleast_1d(anchors)):
            a = np.unique(np.asarray(anchors, dtype=np.int64).ravel())
            if a.min() < 0 or a.max() >= len(muscle.V):
                raise ValueError(f"anchors must index the {len(muscle.V)} fine vertices")
            self.anchors = a
            # feathered: full weight from defaults.anchor_feather rings into the patch on,
            # less toward its rim (a patch held at full weight to its rim creases the
            # muscle there where the rest of it bends far: the iliacus past 90 deg)
            feather = _feather(muscle, a, defaults.anchor_feather)
            self._anchor_W = feather[:, None] * muscle.W[a]
            self._anchor_V = feather[:, None] * muscle.V[a]
            self.anchor_weight = defaults.anchor_weight * np.sqrt(m / len(a))
            w2 = self.anchor_weight**2
            self.H = self.H + w2 * (self._anchor_W.T @ self._anchor_W)
            self._anchor_rhs = w2 * (self._anchor_W.T @ self._anchor_V)
        # explicit inverse for the 3-column solves of the per-pose loop (cond(H) ~ 1e5)
        chol = cho_factor(self.H, lower=False, check_finite=False)
        self._Hinv = cho_solve(chol, np.eye(m), check_finite=False)
        self.rotation_field = RotationField(C, self.rest_samples, self.sample_line, self.spacing)
        self.reference_rest = (
            None if reference_point is None else as_points([reference_point], "reference_point")[0]
        )
        self._sample_rotations = SampleRotations(
            self._rest_means, self.sample_line, reference_rest=self.reference_rest
        )
        self._LT = np.ascontiguousarray(L.T)
        self._ST = np.ascontiguousarray(self.S.T)
        self._diag = float(np.linalg.norm(C.max(0) - C.min(0)))
        # the contact step's groups (each fine vertex's dominant cage vertex) and scale
        self._dominant = np.argmax(muscle.W, axis=1)
        self._fine_edge = mean_edge_length(muscle.V, muscle.F)
        # the default solve's matrices (`_proxy`): x_ls = HL d_L + HS s', and the proxy's
        # coordinates Wd and B = H^-1 Wd^T that make the direction u = B g of a proxy
        # gradient g (`_proxy_matrices`)
        self._HL = self._Hinv @ self._LT
        self._HS = self.weight**2 * (self._Hinv @ self._ST)
        self._x_anchor = self._Hinv @ self._anchor_rhs
        self._proxy_matrices(np.float32)
        L_csr = sparse.csr_matrix(L)
        self._L_csr = (L_csr.indptr.astype(np.int64), L_csr.indices.astype(np.int64), L_csr.data)
        self._line_slices = tuple(
            slice(int(idx[0]), int(idx[-1]) + 1)
            for idx in (np.flatnonzero(self.sample_line == i) for i in range(len(rest)))
        )

    def _attachments(
        self,
        attached: tuple[npt.ArrayLike, npt.ArrayLike] | None,
        rest: Mapping[str, FloatArray],
        m: int,
    ) -> tuple[list[_Held], list[FloatArray]]:
        """The attached vertices per line end (`_Held`), and their rows of ``S``.

        Sets `attached_held`. The rows are the vertices' coordinates times their weight
        over the skeleton's.
        """
        self.attached_held = (0, 0)
        if attached is None:
            return [], []
        mu = self.muscle
        sides = [np.unique(np.asarray(a, dtype=np.int64).ravel()) for a in attached]
        if len(sides) != 2:
            raise ValueError("attached must be two vertex lists: the origin's and the insertion's")
        if any(len(a) and (a[0] < 0 or a[-1] >= len(mu.V)) for a in sides):
            raise ValueError(f"attached vertices must index the {len(mu.V)} fine vertices")
        # per end, the lines that reach the muscle there (their samples there are bound);
        # none: the area is left free. Lines by their index in the samples' order
        names = self.sampling.names
        reach = [
            [i for i, n in enumerate(names) if self.unbound.get(n, (0.0, 0.0, 0.0))[-side] == 0]
            for side in (0, -1)
        ]
        sides = [idx if lines else idx[:0] for idx, lines in zip(sides, reach, strict=True)]
        self.attached_held = (len(sides[0]), len(sides[1]))
        k = sum(self.attached_held)
        if not k:
            return [], []
        scale = defaults.attached_weight * np.sqrt(m / k) / self.weight
        held, rows = [], []
        for side, idx, lines in zip((0, -1), sides, reach, strict=True):
            if not len(idx):
                continue
            ends = np.array([rest[names[i]][side] for i in lines])
            nearest = np.argmin(
                np.linalg.norm(mu.V[idx][:, None, :] - ends[None, :, :], axis=2), axis=1
            )
            for j, i in enumerate(lines):
                r = idx[nearest == j]
                if len(r):
                    held.append(
                        _Held(i, side, mu.V[r] - ends[j], _end_segment(rest[names[i]], side), scale)
                    )
                    rows.append(scale * mu.W[r])
        return held, rows

    def _attached_targets(
        self,
        current_lines: Mapping[str, npt.ArrayLike],
        cur: Mapping[str, FloatArray],
        R_s: FloatArray,
    ) -> FloatArray:
        """The attached vertices' targets in a pose (scaled as their rows of ``S``).

        Each area moves with its line's end point and turns with the body of that point
        (a `PathLines`; plain lines: the line's end sample's rotation ``R_s``), then by
        the least rotation that takes the end segment, so turned, onto where it runs
        now. Under a rigid motion that is the motion; where the path's end segment lies
        on the bone it is the body's rotation; where a tendon joins the area to the
        bone (the rectus femoris below its origin) the area pivots there as the muscle
        does, instead of shearing away from it. ``cur``: the lines validated
        (`check_lines`).
        """
        body = getattr(current_lines, "rotations", None)
        names = self.sampling.names
        out = []
        for h in self._attached:
            n = names[h.line]
            P = cur[n]
            if body is not None:
                # the rotations of the points `check_lines` kept, as `path_rotations` takes them
                raw = np.asarray(current_lines[n], dtype=np.float64)
                R = np.asarray(body[n], dtype=np.float64)[distinct_mask(raw)][h.side]
            else:
                rows = self._line_slices[h.line]
                R = R_s[rows.start if h.side == 0 else rows.stop - 1]
            swing = minimal_rotation((R @ h.segment)[None], _end_segment(P, h.side)[None])[0]
            out.append(h.scale * (h.offset @ (swing @ R).T + P[h.side]))
        return np.concatenate(out)

    def _proxy_matrices(self, dtype: type) -> Deformer:
        """Make the proxy's matrices that steer the default solve, in ``dtype``.

        float32 (the default): they only steer the direction, the fine volume is
        corrected in double precision along it, and half the bytes come through the
        caches each pose. float64 gives the same iteration in double precision, the
        reference of the tests and of ``benchmarks/accuracy/bench_accuracy.py``.
        """
        mu, C = self.muscle, self.muscle.cage.C
        self._steer_Wd = np.ascontiguousarray(mu.proxy_W, dtype=dtype)
        self._steer_B = np.ascontiguousarray(self._Hinv @ mu.proxy_W_T, dtype=dtype)
        # the proxy's rest volume through the same rounded coordinates: exactly kept by a
        # rigid motion, so that one needs no correction
        self._steer_V0 = volume(
            mat3(self._steer_Wd, C - mean_rows(C)), mu.proxy_F, center=np.zeros(3)
        )
        return self

    def _check_near(self, V: FloatArray) -> None:
        """Refuse rest lines that cannot belong to the muscle (`placement_problem`)."""
        samples = {
            name: self.rest_samples[self.sample_line == i]
            for i, name in enumerate(self.sampling.names)
        }
        problem = placement_problem(V, samples)
        if problem is not None:
            raise LineError(
                f"rest lines: {problem}: lines and mesh must share units and coordinate frame "
                "(a mesh in metres with lines in millimetres, lines in metres with a mesh in "
                "millimetres, or a line given in a body's frame, looks like this)"
            )

    @property
    def condition_number(self) -> float:
        """2-norm condition number of ``A^T A`` (computed on first use)."""
        if getattr(self, "_cond", None) is None:
            ev = np.linalg.eigvalsh(self.H)
            self._cond = float(ev[-1] / ev[0])
        return self._cond

    # ------------------------------------------------------------- helpers
    def _solve(self, rhs: FloatArray) -> FloatArray:
        return self._Hinv @ rhs

    def _targets(
        self, current_lines: Mapping[str, npt.ArrayLike], reference_point: npt.ArrayLike | None
    ) -> tuple[dict[str, FloatArray], FloatArray, FloatArray]:
        """Validated current lines, their samples ``s'`` and the rotated deltas ``d_L``.

        The samples' rotations: from the bodies of the lines' points where the lines
        know them (`PathLines`, a model's paths), else from the lines' own frames.
        """
        cur = check_lines(current_lines, "current lines")
        s_cur = self.sampling.evaluate(cur, "current lines")
        body = getattr(current_lines, "rotations", None)
        if body is not None:
            R_s = path_rotations(
                current_lines,
                body,
                self.sampling.names,
                self.sampling.params,
                self.sampling.halfwidths,
                getattr(current_lines, "keys", None),
            )
            s_cur = self._offset(s_cur, R_s)
            if self._attached:
                s_cur = np.vstack([s_cur, self._attached_targets(current_lines, cur, R_s)])
            return cur, s_cur, self.rotation_field.rotate(R_s, self.muscle.delta_rest)
        if (reference_point is None) != (self.reference_rest is None):
            raise ValueError(
                "reference point: give it both at bind (rest) and at deform (current), or neither"
            )
        ref_cur = (
            None if reference_point is None else as_points([reference_point], "reference_point")[0]
        )
        R_s = self._sample_rotations(s_cur, reference_current=ref_cur)
        s_cur = self._offset(s_cur, R_s)
        d_L = self.rotation_field.rotate(R_s, self.muscle.delta_rest)
        if self._attached:
            s_cur = np.vstack([s_cur, self._attached_targets(cur, cur, R_s)])
        return cur, s_cur, d_L

    def _offset(self, means: FloatArray, R_s: FloatArray) -> FloatArray:
        """The samples from their windows' means: each rest point's offset, turned (``R_s``)."""
        if self.sampling.halfwidths is None:
            return means
        return means + np.einsum("kab,kb->ka", R_s, self._sample_offset)

    def _rhs(self, d_L: FloatArray, s_cur: FloatArray) -> FloatArray:
        """``A^T d = L^T d_L + w^2 S^T s'``, the right-hand side of the normal equations."""
        return self._LT @ d_L + self.weight**2 * (self._ST @ s_cur) + self._anchor_rhs

    def energy(self, x: FloatArray, d_L: FloatArray, s_cur: FloatArray) -> float:
        """``||L x - d_L||^2 + w^2 ||S x - s'||^2`` (+ the anchors') of cage positions ``x``."""
        return self._energy_and_samples(x, d_L, s_cur)[0]

    def _energy_and_samples(
        self, x: FloatArray, d_L: FloatArray, s_cur: FloatArray
    ) -> tuple[float, FloatArray]:
        """`energy` and the deformed skeleton samples ``S x``, in one compiled pass."""
        e, Sx = _energy_kernel(
            *self._L_csr,
            self.S,
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(d_L, dtype=np.float64),
            np.ascontiguousarray(s_cur, dtype=np.float64),
            self.weight**2,
        )
        if len(self.anchors):
            r = self._anchor_W @ x - self._anchor_V
            e += self.anchor_weight**2 * float(np.sum(r * r))
        return float(e), Sx

    def _sample_distances(self, Sx: FloatArray, cur: Mapping[str, FloatArray]) -> FloatArray:
        """Each deformed sample's (``S x``) distance to its current line."""
        return np.concatenate(
            [
                _point_polyline_distance(Sx[rows], cur[name])
                for rows, name in zip(self._line_slices, self.sampling.names, strict=True)
            ]
        )

    def _skeleton_fit(self, Sx: FloatArray, cur: Mapping[str, FloatArray]) -> tuple[float, float]:
        """Mean and largest distance of the deformed samples ``S x`` to their current lines."""
        dist = self._sample_distances(Sx, cur)
        return float(dist.mean()), float(dist.max())

    def sample_fits(
        self, x: FloatArray, current_lines: Mapping[str, npt.ArrayLike]
    ) -> tuple[FloatArray, FloatArray]:
        """Each skeleton sample's distance from its current line, and its place on that line.

        ``S x`` (the samples deformed with the cage ``x``) against ``current_lines`` as
        `deform` took them: the distances whose mean is ``skeleton_fit_mean``, and the
        samples' points on the current lines (where they lie inside a bone, the surface
        kept out of it cannot follow them).
        """
        cur = check_lines(current_lines, "current lines")
        s_cur = self._plain.evaluate(cur, "current lines")
        Sx = np.asarray(self.S @ np.asarray(x, dtype=np.float64))
        return self._sample_distances(Sx, cur), s_cur

    def fine_volume_gradient(self, x: FloatArray) -> FloatArray:
        """Gradient of the fine volume w.r.t. cage vertices, ``W^T dV(W x)`` (chain rule)."""
        mu = self.muscle
        c = mean_rows(x)
        return mu.W_T @ volume_gradient(mu.W @ (x - c), mu.F)

    def stationarity(
        self,
        result: DeformationResult,
        current_lines: Mapping[str, npt.ArrayLike],
        reference_point: npt.ArrayLike | None = None,
    ) -> float:
        """Sine of the angle between the energy gradient and the fine volume gradient.

        Zero at an exact KKT point of ``min ||A x - d||^2 s.t. V(W x) = V0``
        (the energy gradient is then parallel to the constraint gradient).
        Returns 0 when the energy gradient itself vanishes (rigid motions).
        """
        _, s_cur, d_L = self._targets(current_lines, reference_point)
        b = self._rhs(d_L, s_cur)
        r = self.H @ result.cage - b
        G = self.fine_volume_gradient(result.cage)
        rn = np.linalg.norm(r)
        if rn <= 1e-12 * np.linalg.norm(b):
            return 0.0
        lam = np.sum(r * G) / np.sum(G * G)
        return float(np.linalg.norm(r - lam * G) / rn)

    # ---------------------------------------------------------------- deform
    def deform(
        self,
        current_lines: Mapping[str, npt.ArrayLike],
        *,
        reference_point: npt.ArrayLike | None = None,
        method: str = "sqp",
        max_iterations: int | None = None,
        alpha: float | None = None,
        obstacles: Sequence[Placed | Obstacle] | None = None,
        margin: float = 0.0,
        finish: bool = True,
        sides: SideReference | None = None,
    ) -> DeformationResult:
        """Deform the muscle so that it follows the current action lines.

        Parameters
        ----------
        current_lines : mapping of str to (k, 3) array_like
            The same lines as at `Muscle.bind`, in the new pose; any number of
            points per line (matched by arc length). A `PathLines` also gives
            each point's body rotation: the samples then turn with their path's
            bodies, and the reference point is not used.
        reference_point : (3,) array_like, optional
            Current position of the reference point (required if one was
            given at `Muscle.bind`, unless the lines are `PathLines`).
        method : {"sqp", "exact", "paper"}, optional
            ``"sqp"`` (default): constrained least squares solved by a few
            fixed-point updates of the volume-gradient direction on a proxy
            mesh, then one exact correction of the FINE volume (the volume
            along a line in cage space is a cubic). ``"exact"``: the same
            iteration with the fine mesh's own gradient every step (a
            reference, about three passes over ``W`` per iteration).
            ``"paper"``: eq. 11 of Kohout et al. (2012), Gauss-Newton with one
            Lagrange multiplier, step ``alpha``, cage volume first and then
            fine volume.
        max_iterations : int, optional
            Iteration limit (defaults per method in `musclewrap.constants`).
        alpha : float, optional
            ``"paper"`` only: a fixed step; default adaptive from 0.5.
        obstacles : sequence of Placed or Obstacle, optional
            Bones in this pose (an `musclewrap.contact.Obstacle` alone is in the
            muscle's frame; a `Placed` carries the transform from the muscle's
            frame into the bone's). After the solve, every fine vertex closer
            than ``margin`` to one of them is moved out onto it and the fine
            volume is restored exactly (`musclewrap.contact.push_out`); a pose
            where that fails is unconverged, with the reason.
        margin : float, optional
            Distance every fine vertex keeps from every obstacle (mesh units).
        finish : bool, optional
            With ``obstacles``: False skips the fine finish (`push_out`), so the
            result's cage, and whatever it carries (fibres), is the same at half
            the cost, while its fine positions keep what the cage's own contact
            steps left (a vertex may stay up to about a mean edge inside a bone).
        sides : SideReference, optional
            With ``obstacles``: an earlier state of the muscle on a path from the
            rest pose to this one (placed against the same obstacles). A vertex
            whose way from there has come through an obstacle is taken back out on
            the side where it entered, not the nearest
            (`musclewrap.contact.on_their_side`); without it every vertex leaves
            an obstacle the nearest way, which is wrong past half a bone's
            thickness.

        Returns
        -------
        DeformationResult

        Raises
        ------
        musclewrap.conditions.LineError
            If the current lines are invalid or name other lines.
        ValueError
            For an unknown method or a reference point given on one side only.
        """
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        t0 = time.perf_counter()
        with np.errstate(all="ignore"):
            # overflow (absurd coordinates) shows as non-finite values, reported below
            cur, s_cur, d_L = self._targets(current_lines, reference_point)
            try:
                if method == "paper":
                    b = self._rhs(d_L, s_cur)
                    x_ls = self._solve(b)
                else:
                    # the unconstrained solution H^-1 A^T d from the two products of its parts
                    x_ls = self._HL @ d_L + self._HS @ s_cur + self._x_anchor
                if not np.isfinite(x_ls).all():
                    raise FloatingPointError("the conditions overflow (line coordinates too large)")
                if method == "paper":
                    x, V, its, ok, reason, hist = self.solve_paper(
                        x_ls,
                        b,
                        d_L,
                        s_cur,
                        max_iterations=max_iterations or defaults.paper_max_iterations,
                        alpha=alpha,
                    )
                elif method == "exact":
                    x, V, its, ok, reason, hist = self._solve_exact(
                        x_ls, d_L, s_cur, max_iterations or defaults.max_iterations
                    )
                else:
                    x, V, its, ok, reason, hist = self._solve_default(
                        x_ls, d_L, s_cur, max_iterations or defaults.max_iterations
                    )
            except (np.linalg.LinAlgError, FloatingPointError) as exc:
                # a singular or overflowing system on this pose: an unconverged result
                # with the reason, never an exception that would end a whole motion
                mu = self.muscle
                return DeformationResult.failed(
                    len(mu.V),
                    len(mu.cage.C),
                    mu.volume_rest,
                    f"numerically singular: {exc}",
                    method=method,
                    seconds=time.perf_counter() - t0,
                )
            contact = None
            if obstacles and np.isfinite(V).all():
                placed = as_placed(obstacles)
                near = Near(V, placed, margin)
                x, V, before, inside = self._cage_contact(x, V, placed, margin, near, sides)
            if obstacles and np.isfinite(V).all() and finish:
                V, contact, ok, reason = self._finish(
                    V, placed, margin, near, sides, before, ok, reason, inside
                )
            res = self._result(x, V, its, ok, reason, hist, cur, d_L, s_cur, method, t0, contact)
            if obstacles and contact is None and np.isfinite(V).all():
                # the finish is the caller's (`settle`): what the solve alone gave, and what
                # the contact found, kept for it
                pose = PoseContact((cur, s_cur, d_L), near, inside, None if inside is None else V)
                res = dataclasses.replace(res, penetration_depth_before=before, pose=pose)
            return res

    def _result(
        self, x, V, its, ok, reason, hist, cur, d_L, s_cur, method, t0, contact=None
    ) -> DeformationResult:  # noqa: ANN001
        mu = self.muscle
        if not np.isfinite(V).all():
            if ok or not reason.startswith("numerically singular"):
                reason = "numerically singular: non-finite positions" + (
                    "" if ok else f" ({reason})"
                )
            ok = False
            V = np.full_like(V, np.nan)
            vol = float("nan")
        else:
            vol = volume(V, mu.F)
        rel = (vol - mu.volume_rest) / mu.volume_rest
        if ok and not abs(rel) <= tol.volume:
            ok, reason = False, f"volume error {rel:.3g} above tolerance {tol.volume:g}"
        energy, fit_mean, fit_max = np.nan, np.nan, np.nan
        if np.isfinite(x).all():
            energy, Sx = self._energy_and_samples(x, d_L, s_cur)
            fit_mean, fit_max = self._skeleton_fit(Sx, cur)
        return DeformationResult(
            V=V,
            cage=x,
            volume_rest=mu.volume_rest,
            volume=vol,
            relative_volume_error=float(rel),
            iterations=its,
            converged=bool(ok),
            reason=reason,
            skeleton_fit_mean=fit_mean,
            skeleton_fit_max=fit_max,
            energy=energy,
            method=method,
            seconds=time.perf_counter() - t0,
            history=tuple(hist),
            **(
                {}
                if contact is None
                else {
                    "contact_vertices": contact.contact_vertices,
                    "penetration_depth": contact.depth_after,
                    "penetration_vertices": contact.inside,
                    "penetration_depth_before": contact.depth_before,
                    "contact_moved": contact.moved_max,
                    "bone_inside_depth": contact.bone_inside_depth,
                    "bone_inside_vertices": contact.bone_inside,
                }
            ),
        )

    def _solve_default(self, x_ls, d_L, s_cur, max_iterations: int) -> Solved:  # noqa: ANN001
        """The default solve (``"sqp"``): every step of its fallback chain, in order.

        The proxy's fixed point, then damped Newton where that is slow, then the
        fine volume along the direction (`_solve_proxy`); where the direction does
        not settle even so (rare: one gait2392 frame of the semitendinosus), the
        exact iteration on the fine mesh's own gradient from the start, and the
        reason says so.
        """
        x, V, its, settled, reason = self._solve_proxy(x_ls, max_iterations)
        if settled is None or settled:
            return Solved(x, V, its, bool(settled), reason, [])
        exact = self._solve_exact(x_ls, d_L, s_cur, max_iterations)
        if not exact.converged:
            return Solved(x, V, its + exact.iterations, False, reason, [])
        why = f"converged by the exact iteration ({reason} on the proxy)"
        return Solved(exact.x, exact.V, its + exact.iterations, True, why, exact.history)

    def _solve_proxy(self, x_ls: FloatArray, max_iterations: int):  # noqa: ANN202
        """The proxy's direction, then the fine volume along it.

        Returns ``x, V, iterations, settled, reason``; ``settled`` is None where no
        finite volume correction exists (V is NaN), else whether the direction
        became stationary.
        """
        mu = self.muscle
        c = mean_rows(x_ls)
        # a few plain fixed-point updates of the direction on the proxy (compiled, `_proxy`)
        lam, u, its, status, best_lam, best_u = plain_iterations(
            mat3(self._steer_Wd, x_ls - c),
            self._steer_Wd,
            self._steer_B,
            mu.proxy_F,
            self._steer_V0,
            plain=min(max_iterations, defaults.plain_iterations),
            tol_dir=tol.direction,
            floor=1e-9 * self._diag,
            rate=defaults.newton_rate,
        )
        if status == PLAIN_NO_ROOT:
            return x_ls, np.full_like(mu.V, np.nan), its, None, "no finite volume correction"
        converged_dir = status == PLAIN_CONVERGED
        if not converged_dir and its < max_iterations:
            # Slow (rate near 1) or oscillating fixed point: damped Newton on the proxy's
            # optimality conditions from the plain iterate of least energy.
            x, lam, n_newton, converged_dir = self._newton(
                x_ls - best_lam * best_u, x_ls, c, max_iterations - its
            )
            its += n_newton
            u = self._solve(mu.proxy_W_T @ volume_gradient(mu.proxy_W @ (x - c), mu.proxy_F))
        # one pass over W: base positions and the correction direction together, then the
        # exact correction of the FINE volume along u (a cubic)
        XU = rows_dot(mu.W, np.hstack([x_ls - c, u]))
        lam_f = cubic_root_near(volume_cubic_pair(XU, mu.F), mu.volume_rest, lam)
        x = x_ls - lam_f * u
        V = combine_pair(XU, lam_f, c)
        reason = (
            "converged" if converged_dir else f"direction not stationary after {its} iterations"
        )
        return x, V, its + 1, converged_dir, reason

    def _solve_exact(self, x_ls, d_L, s_cur, max_iterations: int) -> Solved:  # noqa: ANN001
        """The reference iteration: the fine mesh's own volume gradient every step."""
        mu = self.muscle
        c = mean_rows(x_ls)
        P_ls = mu.W @ (x_ls - c)
        G = mu.W_T @ volume_gradient(P_ls, mu.F)
        lam = 0.0
        x = x_ls
        P = P_ls
        hist: list[tuple[float, float]] = []
        converged_dir = False
        its = 0
        prev_step = 0.0
        for its in range(1, max_iterations + 1):
            u = self._solve(G)
            P_u = mu.W @ u
            lam_new = cubic_root_near(volume_cubic(P_ls, -P_u, mu.F), mu.volume_rest, lam)
            if not np.isfinite(lam_new):
                return Solved(
                    x, np.full_like(mu.V, np.nan), its, False, "no finite volume correction", hist
                )
            x_new = x_ls - lam_new * u
            step = float(np.abs(x_new - x).max())
            x, lam = x_new, lam_new
            P = P_ls - lam * P_u
            hist.append(
                (
                    self.energy(x, d_L, s_cur),
                    volume(P, mu.F, center=np.zeros(3)) / mu.volume_rest - 1,
                )
            )
            size = float(np.abs(lam * u).max())
            done, _ = stationary(step, prev_step, its, size, 1e-9 * self._diag, tol.direction)
            prev_step = step
            if done:
                converged_dir = True
                break
            G = mu.W_T @ volume_gradient(P, mu.F)
        reason = (
            "converged" if converged_dir else f"direction not stationary after {its} iterations"
        )
        return Solved(x, P + c, its, converged_dir, reason, hist)

    def _newton(self, x, x_ls, c, budget: int):  # noqa: ANN001, ANN202
        """Damped Newton on the proxy's KKT system ``H (x - x_ls) + lam g(x) = 0, v(x) = V0``.

        Each step solves ``[(1 + mu) H + lam K, g; g^T, 0]`` (``K`` the volume's Hessian
        in cage space), goes back onto the volume along ``-H^-1 g`` (a cubic) and is kept
        only if the energy ``(x - x_ls)^T H (x - x_ls)`` does not grow; otherwise the
        damping ``mu`` grows (toward a gradient step), and it shrinks after a success
        (Levenberg-Marquardt). Returns ``(x, lam, iterations, converged)``: converged
        when an undamped step is below ``tol.direction`` of the volume correction
        (quadratic convergence leaves about its square).
        """
        mu = self.muscle
        Wd, WdT, Fd, Vd0 = mu.proxy_W, mu.proxy_W_T, mu.proxy_F, mu.proxy_volume_rest
        H = self.H
        k = len(x)
        if getattr(self, "_H3", None) is None:
            self._H3 = np.kron(H, np.eye(3))
        H3 = self._H3

        def energy(y: FloatArray) -> float:
            e = y - x_ls
            return float(np.sum(e * (H @ e)))

        def onto_volume(y: FloatArray) -> FloatArray:
            P = Wd @ (y - c)
            u = self._solve(WdT @ volume_gradient(P, Fd))
            P_u = Wd @ u
            return y - cubic_root_near(volume_cubic(P, -P_u, Fd), Vd0, 0.0) * u

        damp, lam = 0.0, 0.0
        for its in range(1, budget + 1):
            P = Wd @ (x - c)
            G = WdT @ volume_gradient(P, Fd)
            r, g = (H @ (x - x_ls)).ravel(), G.ravel()
            lam = -float(r @ g) / float(g @ g)  # least-squares multiplier at x
            rhs = -np.append(r + lam * g, volume(P, Fd, center=np.zeros(3)) - Vd0)
            K = volume_hessian_reduced(P, Fd, Wd)
            e0 = energy(x)
            for _ in range(40):
                with np.errstate(all="ignore"):
                    try:
                        dx = _kkt_step((1.0 + damp) * H3 + lam * K, g, rhs)
                        x_new = onto_volume(x + dx.reshape(k, 3))
                    except np.linalg.LinAlgError:
                        x_new = None
                if x_new is not None and np.isfinite(x_new).all():
                    if energy(x_new) <= e0 * (1.0 + 1e-12):
                        break
                damp = max(4.0 * damp, 0.25)
            else:
                return x, lam, its, False
            step = float(np.abs(x_new - x).max())
            x = x_new
            size = max(float(np.abs(lam * self._solve(G)).max()), 1e-9 * self._diag)
            if damp == 0.0 and step <= tol.direction * size:
                return x, lam, its, True
            damp = damp / 4.0 if damp > 1e-3 else 0.0
        return x, lam, budget, False


def _feather(muscle: PreparedMuscle, anchors: IntArray, depth: int) -> FloatArray:
    """Per anchor, ``min(1, k / depth)`` for an anchor ``k`` rings from the nearest other vertex."""
    if depth <= 0:
        return np.ones(len(anchors))
    others = np.setdiff1d(np.arange(len(muscle.V)), anchors)
    if not len(others):
        return np.ones(len(anchors))
    level = rings(muscle.adjacency, others, depth)
    return np.minimum(level[anchors] / depth, 1.0)


def _kkt_step(M: FloatArray, g: FloatArray, rhs: FloatArray) -> FloatArray:
    """``dx`` of the bordered system ``[M, g; g^T, 0] [dx; dlam] = rhs`` (one LU).

    ``M`` is symmetric but, with a large multiplier, mostly indefinite: a
    Cholesky first would fail more often than not.
    """
    n = len(g)
    J = np.empty((n + 1, n + 1))
    J[:n, :n] = M
    J[:n, n] = J[n, :n] = g
    J[n, n] = 0.0
    return np.linalg.solve(J, rhs)[:n]

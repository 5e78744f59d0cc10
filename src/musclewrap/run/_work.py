"""The tasks of a run, and what they do in whichever process runs them.

Every task is a frozen dataclass with a ``run()`` method. A worker process keeps the
muscle it deformed last (bound to its rest lines), its fibres and the bone probes it
read, so that the next chunk of the same muscle starts at once; what it builds goes
into the cache folder, which the other workers read.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .._typing import FloatArray, IntArray
from ..conditions import LineError
from ..constants import defaults
from ..contact import Obstacle, Placed, SideReference, line_inside_depth
from ..fibres import Fibres
from ..mesh import apply_transform, invert_rigid, write_mesh
from ..solver import DeformationResult, Deformer, Muscle, facing_at_rest, meet
from ._fibres import fibres_of, frame_fibres, write_frame_fibres
from ._records import (
    BoneMesh,
    ChunkResult,
    Comparison,
    FibreFrame,
    FrameSpan,
    MuscleJob,
    PathSpan,
    PathStates,
    Prepared,
)

__all__ = [
    "Compare",
    "DeformChunk",
    "FollowPath",
    "Prepare",
    "ProbeBone",
    "bone_probe",
    "set_tick",
]

# ---------------------------------------------------------------------------- per process
_tick_sink: Any = None
_probes: dict[tuple[str, str | None], Obstacle] = {}
# per thread (a Dask worker may run several tasks at once): the muscle deformed last
_kept = threading.local()


def _kept_dict(name: str) -> dict[tuple[Any, ...], Any]:
    d = getattr(_kept, name, None)
    if d is None:
        d = {}
        setattr(_kept, name, d)
    return d


def set_tick(sink: Any) -> None:
    """Where this process's frames-done ticks go (an object with ``put(n)``, or None)."""
    global _tick_sink
    _tick_sink = sink


def _tick(n: int = 1) -> None:
    if _tick_sink is not None:
        _tick_sink.put(n)


def _prepare(job: MuscleJob) -> tuple[Muscle, bool, str | None]:
    """The prepared muscle: read from the cache, else built (and cached)."""
    path = job.prepare_path()
    note = None
    if path is not None and path.is_file():
        try:
            # the name is the hash of the input mesh and settings; load() checks the content
            return Muscle.load(path), True, None
        except ValueError as exc:
            note = f"{job.name}: cached preparation unusable ({exc}): rebuilt"
    m = Muscle.from_mesh(
        job.V,
        job.F,
        cage_size=job.cage_size,
        cage_coarsening=job.cage_coarsening,
        source=job.source,
        cleaned=True,  # by the reading, and only moved rigidly since
        input_id=job.input_id,
        cage_around=job.cage_around,
    )
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            m.save(path)
        except OSError as exc:
            note = f"{job.name}: could not write the cache {path} ({exc.strerror})"
    return m, False, note


def bone_probe(bone: BoneMesh, cache_dir: str | None) -> Obstacle:
    """The bone's signed-distance probe: kept per process, cached."""
    key = (bone.probe, cache_dir)
    if key not in _probes:
        _probes[key] = Obstacle.cached(
            bone.V, bone.F, None if cache_dir is None else Path(cache_dir), name=bone.probe
        )
    return _probes[key]


def _probe(job: MuscleJob) -> Callable[[BoneMesh], Obstacle]:
    """The bones' probes with the job's cache (`bone_probe`)."""
    return lambda bone: bone_probe(bone, job.cache_dir)


def _side_poses_note(job: MuscleJob) -> str | None:
    """What the poses either side of a frame (the fibres' moment arms) are solved against."""
    ma = job.moment_arms
    if ma is None or job.contact is None:
        return None  # no moment arms; or no contact in the run, none in its side poses either
    if ma.contact:
        return (
            f"{job.name}: the fibres' moment arms come from side poses solved against the bones "
            "but not the other muscles ([fibres] moment_arm_contact = true)"
        )
    return (
        f"{job.name}: the fibres' moment arms come from side poses solved without contact "
        "([fibres] moment_arm_contact = false): where the muscle presses on a bone or another "
        "muscle they are those of a muscle that would pass into it"
    )


def _attached_note(job: MuscleJob, d: Deformer) -> str | None:
    """Which of the muscle's attachment areas its deformation holds on a body, or None."""
    if job.fibres is None or not job.fibres.attached:
        return None
    parts = []
    for side, end, n in zip(
        ("origin", "insertion"), ("first", "last"), d.attached_held, strict=True
    ):
        if n:
            parts.append(f"its {side}'s on the body of its paths' {end} points ({n} vertices)")
        else:
            parts.append(f"not its {side}'s: its paths run on past the muscle there")
    return f"{job.name}: the attachment areas held ([fibres] attached = true): " + "; ".join(parts)


def _unbound_note(name: str, unbound: dict[str, tuple[float, float, float]]) -> str | None:
    """What of a muscle's lines is not bound to it (`musclewrap.Deformer.unbound`), or None."""
    if not unbound:
        return None
    parts = []
    for line, (start, end, far) in unbound.items():
        where = " and ".join(
            f"its {w} {100 * f:.0f} %" for w, f in (("first", start), ("last", end)) if f > 0
        )
        parts.append(f"{line} ({where}, up to {far:.3g} mesh units outside the muscle)")
    return (
        f"{name}: not bound where the path runs on beyond the muscle (tendons the mesh does "
        f"not hold): {', '.join(parts)}; the muscle follows the rest of its path"
    )


def _deformer(job: MuscleJob, keep: int = 1) -> tuple[Muscle, Deformer, bool, str | None, float]:
    """The muscle bound to its rest lines, kept per process (a muscle comes in chunks).

    The ``keep`` muscles used last are kept (a group of muscles in contact needs them all).
    """
    _deformers = _kept_dict("deformers")
    key = (job.name, job.run)
    if key in _deformers:
        muscle, d = _deformers.pop(key)
        _deformers[key] = (muscle, d)  # used last
        return muscle, d, True, None, 0.0
    t0 = time.perf_counter()
    muscle, hit, note = _prepare(job)
    seconds = time.perf_counter() - t0
    attached = None
    if job.fibres is not None and job.fibres.attached:
        # the fibres' areas (cached with the preparation) held on their paths' end bodies
        fb, _ = _fibres(job, muscle)
        attached = None if fb is None else (fb.origin, fb.insertion)
    d = muscle.bind(
        job.rest_lines,
        reference_point=job.rest_reference,
        anchors=job.anchors,
        line_reach=defaults.line_reach,
        line_window=job.line_window,
        attached=attached,
    )
    while len(_deformers) >= max(1, keep):
        del _deformers[next(iter(_deformers))]  # the one used longest ago
    _deformers[key] = (muscle, d)
    return muscle, d, hit, note, seconds


def _fibres(job: MuscleJob, muscle: Muscle) -> tuple[Fibres | None, str | None]:
    """The muscle's fibres (None without a ``[fibres]`` table), kept per process."""
    if job.fibres is None:
        return None, None
    _fibres_kept = _kept_dict("fibres")
    key = (job.name, job.run)
    if key not in _fibres_kept:
        _fibres_kept.clear()
        _fibres_kept[key] = fibres_of(muscle, job, job.fibres_path(), _probe(job))
    return _fibres_kept[key]  # type: ignore[no-any-return]


# ---------------------------------------------------------------------------- tasks
@dataclass(frozen=True)
class Prepare:
    """A muscle's preparation, and its fibres, into the cache."""

    job: MuscleJob
    fibres_only: bool = False

    def run(self) -> Prepared | None:
        t0 = time.perf_counter()
        muscle, hit, note = _prepare(self.job)
        if self.job.fibres is not None:
            fibres_of(muscle, self.job, self.job.fibres_path(), _probe(self.job))
        if self.fibres_only:
            return None
        return Prepared(self.job.name, time.perf_counter() - t0, hit, note)


@dataclass(frozen=True)
class ProbeBone:
    """A bone's signed-distance probe into the cache."""

    bone: BoneMesh
    cache_dir: str | None

    def run(self) -> None:
        bone_probe(self.bone, self.cache_dir)


@dataclass(frozen=True)
class FollowPath:
    """One muscle at its waypoints, in order, each against its bones from the one before.

    The cage at each waypoint (`PathStates`) is where the frames after it take their
    sides of the bones (`musclewrap.contact.SideReference`): computed once per muscle,
    whichever chunk or worker a frame goes to.
    """

    job: MuscleJob
    span: PathSpan
    keep: int = 1  # muscles kept in the process (`_deformer`): a group's, for its frames

    def run(self) -> PathStates:
        job, span = self.job, self.span
        muscle, d, hit, note, seconds = _deformer(job, self.keep)
        probes = [(bone_probe(b, job.cache_dir), b.name) for b in job.bones]
        K = len(span)
        cages = np.empty((K, len(muscle.cage.C), 3))
        T = {b: np.empty((K, 4, 4)) for _, b in probes}
        reasons = []
        refs: dict[int, SideReference] = {-1: sides_at(muscle, job, probes, None, span.rest_T)}
        for k in range(K):
            place = span.placement(k)
            for b in T:
                T[b][k] = place[b]
            parent = int(span.parent[k])
            x, res = waypoint_cage(
                job, d, probes, span.lines[k], span.references[k], place, refs[parent],
                muscle.cage.C if parent < 0 else cages[parent],
            )  # fmt: skip
            if not res.converged:
                reasons.append((k, res.reason))
            cages[k] = x
            refs[k] = sides_at(muscle, job, probes, x, place)
        return PathStates(
            cages, T, dict(span.rest_T), reasons, Prepared(job.name, seconds, hit, note)
        )


def placed_bones(
    job: MuscleJob,
    probes: list[tuple[Obstacle, str]],
    place: dict[str, FloatArray],
    allow: bool = False,
) -> list[Placed]:
    """The muscle's bones in contact, placed (``place``: the muscle's frame into each bone's).

    ``allow``: with each bone's allowance (the obstacles of a solve), else without (the
    bones a `musclewrap.contact.SideReference` takes the sides of).
    """
    contact = job.contact or {}
    return [
        Placed(probe, place[b], contact[b] if allow else None, b)
        for probe, b in probes
        if b in contact
    ]


def waypoint_cage(
    job: MuscleJob,
    d: Deformer,
    probes: list[tuple[Obstacle, str]],
    lines: dict[str, FloatArray],
    reference: FloatArray | None,
    place: dict[str, FloatArray],
    sides: SideReference | None,
    fallback: FloatArray,
) -> tuple[FloatArray, DeformationResult]:
    """The muscle's cage at a waypoint, against its bones with the sides of the one before.

    ``fallback``: the cage kept where the solve gives no finite positions (the waypoint
    before's). Returns the cage and the solve's result.
    """
    res = d.deform(
        lines,
        reference_point=reference,
        obstacles=placed_bones(job, probes, place, True),
        margin=job.margin,
        sides=sides,
        finish=False,
        method=job.method,
        max_iterations=job.max_iterations,
    )
    x = res.cage
    return (x if np.isfinite(x).all() else fallback), res


def sides_at(
    muscle: Muscle,
    job: MuscleJob,
    probes: list[tuple[Obstacle, str]],
    cage: FloatArray | None,
    place: dict[str, FloatArray],
) -> SideReference:
    """Where the muscle is against its bones in contact: the sides a later pose takes.

    ``cage``: the muscle's cage at a waypoint (None: the muscle at rest); ``place`` the
    bones' placements there (the muscle's frame into each bone's).
    """
    bones = placed_bones(job, probes, place)
    if cage is None:
        return SideReference(muscle.V, bones)
    # every vertex (W itself: W[rows] for every row copied the whole matrix first)
    return SideReference(lambda: muscle.W @ cage, bones, len(muscle.V))


def side_reference(
    muscle: Muscle, job: MuscleJob, probes: list[tuple[Obstacle, str]], path: PathStates, w: int
) -> SideReference:
    """The muscle at waypoint ``w`` of its path (-1: at rest) against its bones."""
    if w < 0:
        return sides_at(muscle, job, probes, None, path.rest_T)
    return sides_at(muscle, job, probes, path.cages[w], {b: T[w] for b, T in path.T.items()})


@dataclass(frozen=True)
class DeformChunk:
    """One muscle on a chunk of frames: deformed, measured, its files written.

    ``path`` (with contact): the muscle at its waypoints, where each frame takes its
    sides of the bones.
    """

    job: MuscleJob
    span: FrameSpan
    path: PathStates | None = None

    def run(self) -> ChunkResult:
        return _deform_chunk(self.job, self.span, self.path)


@dataclass(frozen=True)
class Compare:
    """The paper's iteration beside the default on a few solved frames and the worst.

    ``solved`` are the frames (indices into ``span``) with positions, ``worst`` the
    one with the most iterations, then the largest volume error.
    """

    job: MuscleJob
    span: FrameSpan
    worst: int | None
    solved: tuple[int, ...]
    keep: int = 1  # muscles kept in the process (`_deformer`): a group's, built for its frames

    def run(self) -> Comparison:
        if self.worst is None:
            return Comparison()
        _, d, *_ = _deformer(self.job, self.keep)
        span, worst, solved = self.span, self.worst, self.solved
        spread = np.linspace(0, len(solved) - 1, self.job.paper_frames).round().astype(int)
        picks = {solved[i] for i in spread.tolist()}
        out = Comparison(worst_frame=int(span.frames[worst]))
        for k in sorted(picks | {worst}):
            r = d.deform(span.lines[k], reference_point=span.references[k], method="paper")
            out.paper.append(
                (int(span.frames[k]), r.relative_volume_error, r.iterations, r.seconds)
            )
            if k == worst:
                out.convergence["paper"] = [tuple(h) for h in r.history]
        r = d.deform(span.lines[worst], reference_point=span.references[worst], method="exact")
        out.convergence["exact"] = [tuple(h) for h in r.history]
        return out

    @staticmethod
    def frames_of(rows: list[dict[str, Any]]) -> tuple[int | None, tuple[int, ...]]:
        """The frames solved (with positions) and the worst of them (None: none solved)."""
        solved = [k for k, r in enumerate(rows) if np.isfinite(r["relative_volume_error"])]
        worst = max(
            solved,
            key=lambda k: (rows[k]["iterations"], abs(rows[k]["relative_volume_error"])),
            default=None,
        )
        return worst, tuple(solved)


def _deform_chunk(job: MuscleJob, span: FrameSpan, path: PathStates | None = None) -> ChunkResult:
    c = _MuscleFrames(job, span, path)
    for k in range(len(span)):
        c.emit(k, c.solve_frame(k))
    return c.result


class _MuscleFrames:
    """One muscle on a chunk of frames, in the process that runs it: solve, measure, write.

    ``solve_frame`` solves a frame (``finish=False`` in a `DeformGroup`: the muscles
    meet first, `musclewrap.solver.meet`, which finishes them); ``emit`` measures the
    result, writes its files and adds its report row.
    """

    def __init__(
        self, job: MuscleJob, span: FrameSpan, path: PathStates | None, keep: int = 1
    ) -> None:
        self.job, self.span, self.path = job, span, path
        muscle, d, hit, note, seconds_prepare = _deformer(job, keep)
        self.muscle, self.d = muscle, d
        self.probes = [(bone_probe(b, job.cache_dir), b.name) for b in job.bones]
        self.contact = job.contact  # None (no collisions), or {bone: allowance or None}
        self.out = Path(job.outdir)
        self.result = ChunkResult(job.name, [], [], seconds_prepare=seconds_prepare, cache_hit=hit)
        self.fb, fibre_note = _fibres(job, muscle)
        if job.fibres is not None and not job.fibres.output:
            self.fb = None  # the areas held only (`_deformer`): no fibres written
        if self.fb is not None:
            self.result.fibre_share = [float(x) for x in self.fb.share]
            self.result.fibre_area = [float(x) for x in self.fb.area]
        unbound = _unbound_note(job.name, d.unbound)
        held = _attached_note(job, d)
        sides = _side_poses_note(job) if self.fb is not None else None
        notes = (note, unbound, fibre_note, held, sides)
        self.result.note = "; ".join(n for n in notes if n) or None
        self.kw: dict[str, Any] = {"method": job.method, "max_iterations": job.max_iterations}
        if self.contact is not None:
            self.kw["margin"] = job.margin
        # the sides of the bones, per waypoint (kept: the frames of a chunk share a few)
        self.in_contact = [
            (p, b) for p, b in self.probes if self.contact is not None and b in self.contact
        ]
        self.refs: dict[int, SideReference] = {}

    def sides_of(self, k: int) -> SideReference | None:
        if self.contact is None or self.path is None:
            return None
        span = self.span
        w = -1 if span.waypoint is None else int(span.waypoint[k])
        if w not in self.refs:
            self.refs[w] = side_reference(self.muscle, self.job, self.in_contact, self.path, w)
        return self.refs[w]

    def obstacles(
        self, T: FloatArray, bone_T: dict[str, FloatArray], bones: bool = True
    ) -> list[Placed]:
        """The scene's bones where contact is on (and ``bones``), else None."""
        contact = self.contact
        if contact is None or not bones:
            return None
        return [
            # muscle's body frame -> bone's body frame in one transform
            Placed(probe, invert_rigid(bone_T[bname]) @ T, contact[bname], bname)
            for probe, bname in self.probes
            if bname in contact
        ]

    def solve(
        self,
        lines: dict[str, FloatArray],
        reference: FloatArray | None,
        T: FloatArray,
        bone_T: dict[str, FloatArray],
        finish: bool = True,
        bones: bool = True,
        sides: SideReference | None = None,
    ) -> DeformationResult:

        obstacles = self.obstacles(T, bone_T, bones)
        try:
            return self.d.deform(
                lines,
                reference_point=reference,
                finish=finish,
                obstacles=obstacles,
                sides=sides if obstacles else None,
                **self.kw,
            )
        except LineError as exc:
            # this pose's lines cannot drive the muscle (e.g. a path collapsed to a point):
            # the frame is reported as failed and the motion goes on
            muscle = self.muscle
            return DeformationResult.failed(
                len(muscle.V),
                len(muscle.cage.C),
                muscle.volume_rest,
                f"invalid action lines in this frame: {exc}",
            )

    def frame_obstacles(self, k: int) -> list[Placed]:
        span = self.span
        return self.obstacles(span.to_output[k], {b: TB[k] for b, TB in span.bone_T.items()})

    def solve_frame(self, k: int, finish: bool = True) -> DeformationResult:
        span = self.span
        return self.solve(
            span.lines[k],
            span.references[k],
            span.to_output[k],
            {b: TB[k] for b, TB in span.bone_T.items()},
            finish=finish,
            sides=self.sides_of(k),
        )

    def bones_here(self, k: int) -> dict[str, Any]:
        """Every bone placed in frame ``k`` (the muscle's frame into the bone's)."""
        span, T = self.span, self.span.to_output[k]
        return {
            bname: Placed(probe, invert_rigid(span.bone_T[bname][k]) @ T, None, bname)
            for probe, bname in self.probes
        }

    def penetration(
        self, res: DeformationResult, here: dict[str, Any]
    ) -> tuple[float, float, float]:
        """The muscle's vertices inside bones (count, deepest) and the bones' deepest in it.

        The bones in contact as the contact's finish counted them (exactly); the others
        measured. The bone vertices inside the muscle are found by the contact only
        (without it, not looked for: the whole overlap of every bone, flooded, costs
        more than the pose): NaN there.
        """
        nan = float("nan")
        if not np.isfinite(res.V).all():
            return nan, nan, nan
        contact = self.contact
        n_in, depth, bone_depth = 0, 0.0, nan
        if contact is not None:
            n_in, depth = res.penetration_vertices, res.penetration_depth
            bone_depth = res.bone_inside_depth
        for b, pl in here.items():
            if contact is None or b not in contact:
                n, dep = pl.obstacle.measure(pl.to_obstacle(res.V))
                n_in += n
                depth = max(depth, dep)
        return n_in, depth, bone_depth

    def emit(self, k: int, res: DeformationResult, overlap: float | None = None) -> None:
        """Frame ``k``'s result measured, its files written, its row added.

        ``overlap``: the deepest vertex of this muscle inside another (muscles in
        contact; NaN otherwise).
        """
        sides = self.sides_of(k)
        finite = bool(np.isfinite(res.V).all())  # else no surface to measure or write
        measured = self._measure(k, res, finite)
        if finite:
            self._write_surface(k, res)
        self._write_lines(k)
        if self.fb is not None:
            self._fibres_at(k, res, sides)
        self.result.rows.append(self._row(k, res, overlap, measured))
        _tick()

    def _measure(self, k: int, res: DeformationResult, finite: bool) -> FrameMeasures:
        """Frame ``k``'s shape change, depths in and of the bones, and its lines' in them."""
        shape = float(self.muscle.shape_change(res.V).max()) if finite else float("nan")
        here = self.bones_here(k)
        line_depth = line_inside_depth(
            list(self.span.lines[k].values()), list(here.values()), 0.25 * self.d._fine_edge
        )
        n_in, depth, bone_depth = self.penetration(res, here)
        free, conflict = self._line_fits(k, res, here)
        return FrameMeasures(shape, n_in, depth, bone_depth, line_depth, free, conflict)

    def _line_fits(
        self, k: int, res: DeformationResult, here: dict[str, Any]
    ) -> tuple[float, float]:
        """The skeleton fit where the lines are free, and how far it is off where they are not.

        The skeleton samples split by where their place on the frame's lines lies: outside
        every bone (the mean distance of the deformed samples from the lines there:
        ``skeleton_fit_free``) or inside one, where the surface kept out of the bone cannot
        follow the line (the largest distance there: ``lines_conflict_max``, 0 if none).
        """
        nan = float("nan")
        if not np.isfinite(res.cage).all():
            return nan, nan
        dist, s_cur = self.d.sample_fits(res.cage, self.span.lines[k])
        inside = np.zeros(len(s_cur), dtype=bool)
        for pl in here.values():  # exact, where the grid's bounds cannot decide
            inside[pl.obstacle.query(pl.to_obstacle(s_cur), 0.0)[0]] = True
        free = float(dist[~inside].mean()) if (~inside).any() else nan
        return free, float(dist[inside].max(initial=0.0))

    def _write_surface(self, k: int, res: DeformationResult) -> None:
        """The deformed surface of frame ``k`` in the output frame, with its point arrays."""
        muscle, name, frame = self.muscle, self.job.name, self.span.frames[k]
        fname = f"{name}/{name}_{frame:04d}.vtp"
        write_mesh(
            self.out / fname,
            apply_transform(self.span.to_output[k], res.V),
            muscle.F,
            point_data={
                "input_id": muscle.input_id,
                "area_stretch": muscle.area_stretch(res.V),
            },
        )
        self.result.entries.append((self.span.start + k, fname))

    def _write_lines(self, k: int) -> None:
        """Frame ``k``'s action lines in the output frame, as poly-lines."""
        span, name = self.span, self.job.name
        lname = f"{name}/{name}_lines_{span.frames[k]:04d}.vtp"
        P, segs, o = [], [], 0
        for pts in span.lines[k].values():
            Pp = apply_transform(span.to_output[k], np.asarray(pts, dtype=np.float64))
            P.append(Pp)
            segs += [[o + i, o + i + 1] for i in range(len(Pp) - 1)]
            o += len(Pp)
        write_mesh(self.out / lname, np.vstack(P), np.zeros((0, 3), int), lines=np.array(segs))
        self.result.entries.append((span.start + k, lname))

    def _fibres_at(self, k: int, res: DeformationResult, sides: SideReference | None) -> None:
        """Frame ``k``'s fibres carried, measured (lengths, moment arms) and written."""
        fb, span, name = self.fb, self.span, self.job.name
        assert fb is not None
        frame = span.frames[k]
        got = frame_fibres(
            fb,
            self.muscle.F,
            res,
            k,
            self.job.moment_arms,
            span.side,
            lambda *a, sides=sides, **kw: self.solve(*a, sides=sides, **kw),
        )
        if got["points"] is not None:
            fname = f"{name}/{name}_fibres_{frame:04d}.vtp"
            write_frame_fibres(self.out / fname, fb, got["points"], span.to_output[k])
            self.result.entries.append((span.start + k, fname))
        self.result.fibres.append(
            FibreFrame(
                frame=int(frame),
                time=float(span.times[k]),
                lengths=got["lengths"].tolist(),
                moment_arms=got["moment_arms"].tolist(),
                unconverged=got["unconverged"],
                moved=got["moved"],
                farthest=got["farthest"],
                left=got["left"],
            )
        )

    def _row(
        self, k: int, res: DeformationResult, overlap: float | None, m: FrameMeasures
    ) -> dict[str, Any]:
        """Frame ``k``'s row of report.csv."""
        return {
            "frame": int(self.span.frames[k]),
            "time": float(self.span.times[k]),
            "muscle": self.job.name,
            "iterations": res.iterations,
            "converged": res.converged,
            "relative_volume_error": res.relative_volume_error,
            "skeleton_fit_mean": res.skeleton_fit_mean,
            "seconds": res.seconds,
            "shape_change_max": m.shape,
            "penetration_share": m.inside / len(self.muscle.V),
            "penetration_depth_max": m.depth,
            "bone_inside_depth_max": m.bone_depth,
            "muscle_overlap_max": float("nan") if overlap is None else overlap,
            "muscle_rounds": res.muscle_rounds,
            "contact_vertices": res.contact_vertices,
            "penetration_depth_before": (
                res.penetration_depth_before if self.contact is not None else m.depth
            ),
            "line_inside_depth_max": m.line_depth,
            "skeleton_fit_free": m.fit_free,
            "lines_conflict_max": m.conflict,
            "reason": res.reason,
        }


class FrameMeasures(NamedTuple):
    """A frame's measures for its row: shape change, penetration, the lines in the bones."""

    shape: float
    inside: int  # vertices inside a bone
    depth: float  # the deepest of them (mesh units)
    bone_depth: float  # the deepest bone vertex inside the muscle
    line_depth: float  # the deepest point of the muscle's lines inside a bone
    fit_free: float  # skeleton fit over the samples whose lines lie outside the bones
    conflict: float  # the samples' largest distance from their lines inside a bone


@dataclass(frozen=True)
class DeformGroup:
    """Muscles that may touch each other, on a chunk of frames: each frame solved together.

    Per frame, every muscle is solved against its bones (without the fine finish),
    then they meet (`musclewrap.solver.meet`: rounds in which each takes half of its
    depth in another out, then its bone finish). The muscles go in the order of
    their names: the files do not depend on the order the scene lists them in, nor
    on the chunks or the workers.

    ``to_common`` per muscle: the transform from its frame into the scene's, at rest
    (where the faces that face each other are found). ``pairs``: those kept apart
    (``[collisions] pairs``; None: every pair).
    """

    jobs: tuple[MuscleJob, ...]
    spans: tuple[FrameSpan, ...]
    paths: tuple[PathStates | None, ...]
    to_common: tuple[FloatArray, ...]
    pairs: tuple[tuple[str, str], ...] | None = None

    def run(self) -> dict[str, ChunkResult]:

        order = sorted(range(len(self.jobs)), key=lambda i: self.jobs[i].name)
        ms = {
            self.jobs[i].name: _MuscleFrames(
                self.jobs[i], self.spans[i], self.paths[i], keep=len(self.jobs)
            )
            for i in order
        }
        ds = {n: m.d for n, m in ms.items()}
        # where they face each other at rest: once per run in this process (every chunk of
        # the run's frames needs the same)
        kept = _kept_dict("facing")
        key = (self.jobs[0].run, tuple(ms))
        if key not in kept:
            kept.clear()
            cache = self.jobs[0].cache_dir
            kept[key] = facing_at_rest(
                ds,
                {self.jobs[i].name: self.to_common[i] for i in order},
                cache=None if cache is None else Path(cache),
            )
        facing = kept[key]
        margin = self.jobs[0].margin
        for k in range(len(self.spans[0])):
            final = meet_frame(ms, k, facing, margin, self.pairs, self.jobs[0].together)
            for n, m in ms.items():
                m.emit(k, final[n], final[n].muscle_overlap)
        return {n: m.result for n, m in ms.items()}


def meet_frame(
    ms: dict[str, _MuscleFrames],
    k: int,
    facing: dict[tuple[str, str], IntArray],
    margin: float,
    pairs: tuple[tuple[str, str], ...] | None,
    together: bool = False,
) -> dict[str, DeformationResult]:
    """Frame ``k`` of muscles in contact, solved together.

    Each against its bones, then they meet (`musclewrap.solver.meet`); ``ms`` in the
    order of their names.
    """
    return meet(
        {n: m.d for n, m in ms.items()},
        {n: m.solve_frame(k, finish=False) for n, m in ms.items()},
        {n: m.span.lines[k] for n, m in ms.items()},
        frames={n: m.span.to_output[k] for n, m in ms.items()},
        reference_points={n: m.span.references[k] for n, m in ms.items()},
        obstacles={n: m.frame_obstacles(k) for n, m in ms.items()},
        margin=margin,
        sides={n: m.sides_of(k) for n, m in ms.items()},
        facing=facing,
        pairs=pairs,
        together=together,
    )

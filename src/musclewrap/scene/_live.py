"""A scene held open: any pose solved as a run solves it, for the live viewer.

`LiveScene` reads a scene as a run does (the same meshes, cache, contact settings and
rest-pose outcome), prepares its muscles once, and then solves one pose at a time:
a frame of the motion, or any values of the coordinates the scene drives. A pose
goes through the run's own code: the model posed by the drive's `._drive.Poser`, the
waypoints between the rest pose and the pose deformed in order as `._work.FollowPath`
does (kept, so that a nearby pose reuses them), then the pose solved by
`._work._MuscleFrames` (each muscle alone, or together with `._work.meet_frame`
where the muscles are kept apart). So a pose shown equals the run's files for the
same pose: `write` writes them with the run's own writer.
"""

from __future__ import annotations

import dataclasses
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import FloatArray, IntArray
from ..mesh import write_mesh
from ._config import Scene, load_scene
from ._drive import apply, invert_rigid, lattice_parent
from ._errors import SceneError
from ._plan import FrameSpan, PathStates, muscle_jobs
from ._read import Inputs, default_cache_dir, read_inputs
from ._work import (
    Prepare,
    _MuscleFrames,
    bone_probe,
    meet_frame,
    placed_bones,
    waypoint_cage,
)
from ._write import _bone_display

__all__ = ["CheckError", "Coordinate", "LiveScene", "PoseResult"]

#: vertices within this distance of a bone (mesh units: mm) are coloured as in contact
CONTACT_REACH = 5.0


class CheckError(SceneError):
    """The scene fails `check_scene`: what ``run`` refuses to run (``report`` says why)."""

    def __init__(self, scene: Scene, report: Any) -> None:
        self.report = report
        super().__init__(refusal(scene, report))


def refusal(scene: Scene, report: Any) -> str:
    """What ``run`` prints for a scene its check refuses (the findings, one a line)."""
    return "\n".join(
        [
            f"{scene.path}: the scene's check found what would make the run wrong:",
            *(f"  {f}" for f in report.findings),
            "(musclewrap check SCENE -o check.png shows it; --no-check runs anyway)",
        ]
    )


@dataclass(frozen=True)
class Coordinate:
    """A coordinate the scene drives: its range (the model's) and its unit on the slider.

    Values are in the motion's units: degrees (or radians, as the motion gives them) for
    a rotational coordinate, model units for a translational one.
    """

    name: str
    low: float
    high: float
    unit: str
    rotational: bool


@dataclass
class PoseResult:
    """One pose solved: positions in the output frame and the run's figures for it.

    ``muscles[name]`` (n, 3) the deformed vertices (NaN where the solve failed),
    ``stretch`` their `musclewrap.solver.Muscle.area_stretch`, ``gap`` each vertex's
    distance to the nearest bone (mesh units, capped at `CONTACT_REACH`; negative
    inside), ``bones[name]`` each bone's transform into the output frame, ``lines``
    each muscle's action lines, ``fibres`` their points (N, K, 3) where the scene has
    fibres. ``rows`` per muscle: ``relative_volume_error``, ``penetration_depth_max``,
    ``muscle_overlap_max``, ``converged``, ``reason``, ``iterations``.
    """

    values: dict[str, float]
    frame: int | None
    muscles: dict[str, FloatArray]
    stretch: dict[str, FloatArray]
    gap: dict[str, FloatArray]
    bones: dict[str, FloatArray]
    lines: dict[str, list[FloatArray]]
    fibres: dict[str, FloatArray]
    rows: dict[str, dict[str, Any]]
    seconds: dict[str, float] = field(default_factory=dict)
    #: what the pose's files need (`LiveScene.write`)
    solved: Any = field(default=None, repr=False)

    @property
    def volume_error(self) -> float:
        """The largest absolute relative volume error over the muscles."""
        return max(abs(r["relative_volume_error"]) for r in self.rows.values())

    @property
    def penetration(self) -> float:
        """The deepest muscle vertex inside a bone (mesh units)."""
        return max(r["penetration_depth_max"] for r in self.rows.values())

    @property
    def overlap(self) -> float:
        """The deepest vertex of a muscle inside another (NaN: muscles not kept apart)."""
        v = [r["muscle_overlap_max"] for r in self.rows.values()]
        return float("nan") if all(np.isnan(v)) else float(np.nanmax(v))

    @property
    def unconverged(self) -> dict[str, str]:
        """The muscles whose solve did not converge at this pose, with why."""
        return {n: r["reason"] for n, r in self.rows.items() if not r["converged"]}


class LiveScene:
    """A scene read and prepared once; `solve` deforms it at any pose, as a run would.

    Parameters
    ----------
    scene : Scene or path
        The scene (a TOML file or `load_scene`'s result).
    cache_dir : path, True or False
        As `run_scene`'s (True: the scene's or the default cache).
    check : bool
        Run `check_scene` first, as ``musclewrap run`` does: a scene it refuses raises
        `CheckError` with run's message.
    collisions : bool, optional
        As `run_scene`'s.
    log : callable, optional
        Receives the reading's notes as they come.

    The solves run in whichever thread calls `solve` first; call it from one thread
    (the muscles bound to their lines are kept per thread, as in a run's worker).
    """

    def __init__(
        self,
        scene: Scene | str | os.PathLike[str],
        *,
        cache_dir: Path | bool = True,
        check: bool = True,
        collisions: bool | None = None,
        log: Callable[[str], None] | None = None,
    ) -> None:
        from threadpoolctl import threadpool_limits

        self.scene = scene = scene if isinstance(scene, Scene) else load_scene(scene)
        say = log or (lambda _: None)
        if cache_dir is True:
            cache = scene.cache_dir or default_cache_dir()
        else:
            cache = None if cache_dir is False else Path(cache_dir)
        self.cache = cache
        if check:
            from ._check import check_scene

            rep = check_scene(scene, cache_dir=cache if cache is not None else False)
            if not rep.ok:
                raise CheckError(scene, rep)
        on = scene.collisions if collisions is None else bool(collisions and scene.bones)
        self.grouped = (
            collisions is not False and scene.muscle_collisions and len(scene.muscles) > 1
        )
        self.notes: list[str] = []
        inputs: Inputs = read_inputs(
            scene, None, cache, on, say, self.notes, None, self.grouped, keep_poser=True
        )
        self.inputs, drive = inputs, inputs.drive
        self.drive = drive
        self.poser = drive.poser
        self.jobs = sorted(
            muscle_jobs(inputs, Path("."), os.urandom(8).hex()), key=lambda j: j.name
        )
        self.specs = {m.name: m for m in scene.muscles}
        self.bone_body = {b.name: b.body for b in scene.bones}
        with threadpool_limits(1, user_api="blas"):
            for j in self.jobs:
                Prepare(j).run()  # from the cache, else built into it
            for b in inputs.bones.values():
                bone_probe(b, None if cache is None else str(cache))
        self._thread: int | None = None
        self._frames: dict[str, _MuscleFrames] = {}
        self._facing: Any = None
        self._nodes: dict[tuple[int, ...], dict[str, tuple[FloatArray, dict[str, FloatArray]]]] = {}
        self._lock = threading.Lock()
        self.coordinates = self._coordinates()

    # ------------------------------------------------------------------ what can be posed
    def _coordinates(self) -> list[Coordinate]:
        p = self.poser
        if p is None:
            return []
        out = []
        for c in p.coordinates:
            lo, hi = p.model.coordinate_range(c)
            rot = bool(p.model.is_rotational(c))
            if rot and p.degrees:
                lo, hi = float(np.degrees(lo)), float(np.degrees(hi))
            unit = ("deg" if p.degrees else "rad") if rot else self.scene.model_unit
            out.append(Coordinate(c, float(lo), float(hi), unit, rot))
        return out

    @property
    def n_frames(self) -> int:
        """The motion's frames (or the line CSV's)."""
        return len(self.drive.frames)

    @property
    def times(self) -> FloatArray:
        """Each frame's time (s)."""
        return np.asarray(self.drive.times)

    def frame_values(self, k: int) -> dict[str, float]:
        """The driven coordinates at frame position ``k`` (the motion's units, as read)."""
        p = self.poser
        if p is None:
            return {}
        return {c: float(v[k]) for c, v in p.motion_values.items()}

    # ------------------------------------------------------------------ solving
    def _muscle_frames(self) -> dict[str, _MuscleFrames]:
        """Each muscle's solver (built once, in the thread that solves)."""
        me = threading.get_ident()
        if self._thread is None:
            self._thread = me
        elif self._thread != me:
            raise RuntimeError("LiveScene.solve is called from one thread only")
        if not self._frames:
            for j in self.jobs:
                span = self._span(j.name, [{}], [None], {}, None)
                self._frames[j.name] = _MuscleFrames(j, span, None, keep=len(self.jobs))
        return self._frames

    def _span(
        self,
        name: str,
        lines: list[Any],
        refs: list[Any],
        out_T: dict[str, FloatArray],
        waypoint: int | None,
        time_s: float = 0.0,
        frame: int = 0,
    ) -> FrameSpan:
        spec = self.specs[name]
        eye = np.eye(4)[None]
        return FrameSpan(
            0,
            np.array([frame]),
            np.array([time_s]),
            lines,
            refs,
            out_T[spec.body][None] if out_T else eye,
            {b: (out_T[body][None] if out_T else eye) for b, body in self.bone_body.items()},
            None,
            None if waypoint is None else np.array([waypoint]),
        )

    def _waypoint_states(self, pose: dict[str, float]) -> dict[str, PathStates | None]:
        """Per muscle, the cage at the pose's waypoint (the run's `FollowPath`, kept)."""
        p = self.poser
        jobs = [j for j in self.jobs if j.contact is not None]
        if p is None or not jobs or self.drive.waypoints is None:
            return {
                j.name: _rest_path(self, j) if j.contact is not None else None for j in self.jobs
            }
        wp = self.drive.waypoints
        r, steps = np.asarray(wp.rest), np.asarray(wp.steps)
        u = (np.array([pose[c] for c in wp.coordinates]) - r) / steps
        chain = []
        node = lattice_parent(u)
        while np.any(node != 0):
            chain.append(tuple(int(x) for x in node))
            node = lattice_parent(node)
        chain.reverse()
        frames = self._muscle_frames()
        for i, key in enumerate(chain):
            if key in self._nodes:
                continue
            parent = chain[i - 1] if i else None
            q = {
                **p.rest,
                **dict(zip(wp.coordinates, (r + np.array(key) * steps).tolist(), strict=True)),
            }
            L, R, out_T = p.at(q)
            got = {}
            for j in jobs:
                m = frames[j.name]
                spec = self.specs[j.name]
                place = {
                    b: invert_rigid(out_T[self.bone_body[b]]) @ out_T[spec.body]
                    for b in self.bone_body
                }
                if parent is None:
                    sides = _rest_sides(self, j, m)
                    fallback = m.muscle.cage.C
                else:
                    cage0, place0 = self._nodes[parent][j.name]
                    sides = _sides(j, m, cage0, place0)
                    fallback = cage0
                x, _ = waypoint_cage(
                    j, m.d, m.in_contact, L[j.name], R[j.name], place, sides, fallback
                )
                got[j.name] = (x, place)
            self._nodes[key] = got
        out: dict[str, PathStates | None] = {}
        for j in self.jobs:
            if j.contact is None:
                out[j.name] = None
            elif not chain:
                out[j.name] = _rest_path(self, j)
            else:
                x, place = self._nodes[chain[-1]][j.name]
                out[j.name] = PathStates(
                    x[None], {b: T[None] for b, T in place.items()}, _rest_T(self, j.name)
                )
        return out

    def solve(
        self, values: dict[str, float] | None = None, *, frame: int | None = None
    ) -> PoseResult:
        """Deform every muscle at a pose: ``values`` of the driven coordinates, or a frame.

        ``values`` (the motion's units, see `Coordinate`) set the coordinates they
        name; the others stay at the rest pose. ``frame`` (a position in the motion):
        that frame's pose, as the run drives it (a line CSV's scene: frames only).
        """
        from threadpoolctl import threadpool_limits

        with self._lock, threadpool_limits(1, user_api="blas"):
            return self._solve(values, frame)

    def _solve(self, values: dict[str, float] | None, frame: int | None) -> PoseResult:
        t0 = time.perf_counter()
        p, drive = self.poser, self.drive
        if frame is not None and not 0 <= frame < self.n_frames:
            raise ValueError(f"frame {frame} is not a frame of the motion (0..{self.n_frames - 1})")
        if p is None:
            if frame is None:
                raise ValueError(
                    f"{self.scene.path}: a line CSV's scene is posed by its frames only"
                )
            L = {n: drive.lines[n][frame] for n in self.specs}
            R = {n: drive.references[n][frame] for n in self.specs}
            out_T = {b: T[frame] for b, T in drive.to_output.items()}
            paths: dict[str, PathStates | None] = {
                j.name: _rest_path(self, j) if j.contact is not None else None for j in self.jobs
            }
            shown = {}
        else:
            if frame is not None:
                values = self.frame_values(frame)
            values = dict(values or {})
            unknown = [c for c in values if c not in p.coordinates]
            if unknown:
                raise ValueError(
                    f"{self.scene.path}: the scene drives {', '.join(p.coordinates)}; not "
                    + ", ".join(unknown)
                )
            pose = p.pose(values)
            shown = {c: float(values.get(c, _back(p, c, pose[c]))) for c in p.coordinates}
            paths = self._waypoint_states(pose)
            L, R, out_T = p.at(pose)
        t_path = time.perf_counter()
        ms = self._muscle_frames()
        for j in self.jobs:
            m = ms[j.name]
            m.span = self._span(
                j.name,
                [L[j.name]],
                [R[j.name]],
                out_T,
                None if paths[j.name] is None else 0,
                0.0 if frame is None else float(drive.times[frame]),
                0 if frame is None else int(drive.frames[frame]),
            )
            m.path = paths[j.name]
            m.refs = {}
            if m.path is not None and m.path.cages.shape[0] == 0:
                m.span = dataclasses.replace(m.span, waypoint=np.array([-1]))
        if self.grouped:
            if self._facing is None:
                from ..solver import facing_at_rest

                to_common = {j.name: np.linalg.inv(drive.to_body[j.name]) for j in self.jobs}
                self._facing = facing_at_rest({n: m.d for n, m in ms.items()}, to_common)
            results = meet_frame(ms, 0, self._facing, self.jobs[0].margin, self.scene.muscle_pairs)
        else:
            results = {n: m.solve_frame(0) for n, m in ms.items()}
        t_solve = time.perf_counter()
        res = self._measure(ms, results, shown, frame, out_T, L)
        res.seconds = {
            "path": t_path - t0,
            "solve": t_solve - t_path,
            "measure": time.perf_counter() - t_solve,
        }
        res.solved = (ms, results, out_T)
        return res

    def _measure(
        self,
        ms: dict[str, _MuscleFrames],
        results: dict[str, Any],
        shown: dict[str, float],
        frame: int | None,
        out_T: dict[str, FloatArray],
        L: dict[str, Any],
    ) -> PoseResult:
        muscles, stretch, gap, rows, lines, fibres = {}, {}, {}, {}, {}, {}
        for n, m in ms.items():
            r = results[n]
            T = m.span.to_output[0]
            here = m.bones_here(0)
            _, depth, _ = m.penetration(r, here)
            ok = np.isfinite(r.V).all()
            muscles[n] = apply(T, r.V)
            stretch[n] = m.muscle.area_stretch(r.V) if ok else np.full(len(r.V), np.nan)
            g = np.full(len(r.V), CONTACT_REACH)
            if ok:
                for pl in here.values():
                    # the grid's trilinear distance: for the colours, not a verdict
                    idx, phi, _ = pl.obstacle.interpolate(pl.to_obstacle(r.V), CONTACT_REACH)
                    g[idx] = np.minimum(g[idx], phi)
            gap[n] = g
            lines[n] = [apply(T, np.asarray(P, dtype=np.float64)) for P in L[n].values()]
            if m.fb is not None and ok:
                from ._fibres import frame_fibres

                got = frame_fibres(m.fb, m.muscle.F, r, 0, None, None, m.solve)
                if got["points"] is not None:
                    fibres[n] = apply(T, got["points"].reshape(-1, 3)).reshape(got["points"].shape)
            rows[n] = {
                "relative_volume_error": r.relative_volume_error,
                "penetration_depth_max": depth,
                "muscle_overlap_max": r.muscle_overlap if self.grouped else float("nan"),
                "converged": bool(r.converged),
                "reason": r.reason,
                "iterations": r.iterations,
            }
        bones = {b: out_T[body] for b, body in self.bone_body.items()} if out_T else {}
        return PoseResult(shown, frame, muscles, stretch, gap, bones, lines, fibres, rows)

    def bone_meshes(self, faces: int | None = None) -> dict[str, tuple[FloatArray, IntArray]]:
        """Each bone's display mesh in its body's frame (the run's, decimated as it does)."""
        n = self.scene.bone_display_faces if faces is None else faces
        return {b.name: _bone_display(b.V, b.F, n, self.cache) for b in self.inputs.bones.values()}

    def write(self, result: PoseResult, folder: str | os.PathLike[str]) -> list[Path]:
        """Write a solved pose's files as a run writes frame 0 of a one-frame motion.

        ``<muscle>/<muscle>_0000.vtp`` (with its lines and fibres), each bone's mesh, and
        ``pose.json`` (the coordinates' values). Returns the files written.
        """
        import json

        from ._plan import ChunkResult

        folder = Path(folder)
        ms, results, out_T = result.solved
        written: list[Path] = []
        for n, m in ms.items():
            w = _MuscleFrames.__new__(_MuscleFrames)
            w.__dict__.update(m.__dict__)
            w.out = folder
            w.result = ChunkResult(n, [], [])
            w.emit(0, results[n], results[n].muscle_overlap if self.grouped else None)
            written += [folder / f for _, f in w.result.entries]
        for b, (V, F) in self.bone_meshes().items():
            f = folder / b / f"{b}.vtp"
            write_mesh(f, apply(out_T[self.bone_body[b]], V) if out_T else V, F)
            written.append(f)
        f = folder / "pose.json"
        f.write_text(
            json.dumps(
                {"scene": str(self.scene.path), "frame": result.frame, "values": result.values},
                indent=1,
            ),
            encoding="utf-8",
        )
        written.append(f)
        return written


def _back(p: Any, c: str, q: float) -> float:
    """A coordinate's pose value (model units) in the motion's units."""
    return float(np.degrees(q)) if (p.degrees and p.model.is_rotational(c)) else float(q)


def _rest_T(live: LiveScene, name: str) -> dict[str, FloatArray]:
    body = live.specs[name].body
    return {b: live.drive.rest_between(body, bb) for b, bb in live.bone_body.items()}


def _rest_path(live: LiveScene, job: Any) -> PathStates:
    """No waypoint: the pose takes its sides from the rest pose."""
    return PathStates(
        np.zeros((0, 0, 3)),
        {b: np.zeros((0, 4, 4)) for b in live.bone_body},
        _rest_T(live, job.name),
    )


def _rest_sides(live: LiveScene, job: Any, m: _MuscleFrames) -> Any:
    from ..contact import SideReference

    return SideReference(m.muscle.V, placed_bones(job, m.in_contact, _rest_T(live, job.name)))


def _sides(job: Any, m: _MuscleFrames, x: FloatArray, place: dict[str, FloatArray]) -> Any:
    from ..contact import SideReference

    return SideReference(
        lambda rows: m.muscle.W[rows] @ x, placed_bones(job, m.in_contact, place), len(m.muscle.V)
    )

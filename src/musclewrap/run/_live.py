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

import copy
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import ThreadpoolController

from .._typing import FloatArray, IntArray
from ..constants import defaults
from ..contact import every_pair, muscle_gaps
from ..errors import SceneError
from ..mesh import apply_transform, invert_rigid, write_mesh
from ..scene import Scene, lattice_paths, load_scene
from ..solver import facing_at_rest
from ._check import CheckReport, check_scene
from ._fibres import frame_fibres
from ._plan import muscle_jobs, rest_placements
from ._read import Inputs, default_cache_dir, read_inputs
from ._records import ChunkResult, FrameSpan, PathStates
from ._run import picture_view
from ._work import _MuscleFrames, meet_frame, sides_at, waypoint_cage
from ._write import _bone_display

__all__ = ["CheckError", "Coordinate", "LiveScene", "PoseResult", "refusal"]


#: the waypoints whose sides of the bones are kept (each muscle's, a few MB each)
_SIDES_KEPT = 8


class CheckError(SceneError):
    """The scene fails `check_scene`: what ``run`` refuses to run (``report`` says why)."""

    def __init__(self, scene: Scene, report: CheckReport) -> None:
        self.report = report
        super().__init__(refusal(scene, report))


def refusal(scene: Scene, report: CheckReport) -> str:
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
    ``stretch`` their `musclewrap.solver.Muscle.area_stretch`, ``bones[name]`` each
    bone's transform into the output frame, ``lines`` each muscle's action lines,
    ``fibres`` their points (N, K, 3) where the scene has fibres. ``rows`` per muscle:
    ``relative_volume_error``, ``penetration_depth_max``, ``muscle_overlap_max``,
    ``converged``, ``reason``, ``iterations``. ``pairs`` the pairs of muscles the run
    keeps apart (none where it does not). `LiveScene.contact` measures each vertex's
    distance to what it is kept out of.
    """

    values: dict[str, float]
    frame: int | None
    muscles: dict[str, FloatArray]
    stretch: dict[str, FloatArray]
    bones: dict[str, FloatArray]
    lines: dict[str, list[FloatArray]]
    fibres: dict[str, FloatArray]
    rows: dict[str, dict[str, Any]]
    seconds: dict[str, float] = field(default_factory=dict)
    #: the pose's solvers (each muscle's as it was at this pose), results and output
    #: transforms: what its files and its contact need (`LiveScene.write`, `.contact`)
    solved: Any = field(default=None, repr=False)
    pairs: list[tuple[str, str]] = field(default_factory=list)
    #: `LiveScene.contact`'s, once computed
    contact: dict[str, FloatArray] | None = field(default=None, init=False, repr=False)

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
    prepare : bool
        Build each muscle's solver now (its preparation from the cache, its bones'
        probes). False: on the first `solve` (the viewer serves its page meanwhile).

    `solve` may be called from any thread; one pose is solved at a time.
    """

    def __init__(
        self,
        scene: Scene | str | os.PathLike[str],
        *,
        cache_dir: Path | bool = True,
        check: bool = True,
        collisions: bool | None = None,
        log: Callable[[str], None] | None = None,
        prepare: bool = True,
    ) -> None:
        self.scene = scene = scene if isinstance(scene, Scene) else load_scene(scene)
        say = log or (lambda _: None)
        if cache_dir is True:
            cache = scene.cache_dir or default_cache_dir()
        else:
            cache = None if cache_dir is False else Path(cache_dir)
        self.cache = cache
        if check:
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
        #: the pairs of muscles kept apart (as the run keeps them; none where it does not)
        self.pairs = every_pair(sorted(self.specs), scene.muscle_pairs) if self.grouped else []
        self.bone_body = {b.name: b.body for b in scene.bones}
        self._facing: Any = None
        # per waypoint (its lattice point), per muscle in contact: its cage and bones there
        self._nodes: dict[tuple[int, ...], dict[str, tuple[FloatArray, dict[str, FloatArray]]]] = {}
        # per waypoint (None: the rest pose), per muscle: its sides there (`_sides`)
        self._refs: dict[tuple[int, ...] | None, dict[str, dict[int, Any]]] = {}
        self._rest_T = {j.name: rest_placements(inputs, j.name) for j in self.jobs}
        self._lock = threading.Lock()
        # BLAS on one thread while solving, as a run's workers (found once: ~1 ms a search)
        self._pools = ThreadpoolController()
        self._built: dict[str, _MuscleFrames] | None = None
        self.coordinates = self._coordinates()
        if prepare:
            self.prepare()

    def prepare(self) -> None:
        """Build each muscle's solver, if not yet done (`solve` does it first)."""
        with self._lock, self._pools.limit(limits=1, user_api="blas"):
            self._prepare()

    def _prepare(self) -> dict[str, _MuscleFrames]:
        # each muscle's solver, as a run's chunk holds it: prepared (from the cache, else built
        # into it), bound to its rest lines, with its bones' probes and its fibres
        if self._built is None:
            self._built = {
                j.name: _MuscleFrames(j, self._span(j.name, [{}], [None], {}), None, len(self.jobs))
                for j in self.jobs
            }
        return self._built

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
    def _span(
        self,
        name: str,
        lines: list[Any],
        refs: list[Any],
        out_T: dict[str, FloatArray],
        waypoint: int | None = None,
        time_s: float = 0.0,
        frame: int = 0,
    ) -> FrameSpan:
        """A one-frame span of muscle ``name`` (``out_T``: each body's output transform)."""
        eye = np.eye(4)
        return FrameSpan(
            0,
            np.array([frame]),
            np.array([time_s]),
            lines,
            refs,
            out_T.get(self.specs[name].body, eye)[None],
            {b: out_T.get(body, eye)[None] for b, body in self.bone_body.items()},
            None,
            None if waypoint is None else np.array([waypoint]),
        )

    def _paths(
        self, pose: dict[str, float] | None
    ) -> tuple[dict[str, PathStates | None], tuple[int, ...] | None]:
        """Per muscle in contact, its cage at the pose's waypoint (None: no contact).

        The run's `FollowPath` on the lattice of `._drive.lattice_paths` from the rest
        pose to ``pose`` (None: a line CSV's frame, which has no waypoints), each
        waypoint solved once and kept: poses near each other share them. An empty
        `PathStates`: the pose takes its sides from the rest pose. Also the waypoint's
        lattice point (None: the rest pose).
        """
        p, wp = self.poser, self.drive.waypoints
        jobs = [j for j in self.jobs if j.contact is not None]
        key: tuple[int, ...] | None = None
        if pose is not None and p is not None and wp is not None and jobs:
            r, steps = np.asarray(wp.rest), np.asarray(wp.steps)
            u = (np.array([pose[c] for c in wp.coordinates]) - r) / steps
            nodes, parent, at = lattice_paths(u[None])
            keys = [tuple(int(x) for x in n) for n in nodes]
            for k, here in enumerate(keys):
                if here not in self._nodes:
                    q = dict(zip(wp.coordinates, (r + nodes[k] * steps).tolist(), strict=True))
                    before = None if parent[k] < 0 else keys[parent[k]]
                    self._nodes[here] = self._waypoint(p.at({**p.rest, **q}), before, jobs)
            key = None if at[0] < 0 else keys[at[0]]
        out: dict[str, PathStates | None] = {j.name: None for j in self.jobs}
        for j in jobs:
            if key is None:
                cages, T = np.zeros((0, 0, 3)), {b: np.zeros((0, 4, 4)) for b in self.bone_body}
            else:
                x, place = self._nodes[key][j.name]
                cages, T = x[None], {b: M[None] for b, M in place.items()}
            out[j.name] = PathStates(cages, T, self._rest_T[j.name])
        return out, key

    def _sides(self, key: tuple[int, ...] | None) -> dict[str, dict[int, Any]]:
        """Per muscle, its sides of the bones at waypoint ``key`` (as `_MuscleFrames.refs`).

        Kept for the last few waypoints: a `contact.SideReference` keeps what it
        computed of its state (every vertex against each bone then), and the poses of a
        drag take their sides from a few waypoints (a run's chunk keeps them likewise).
        """
        got = self._refs.pop(key, None)
        if got is None:
            got = {j.name: {} for j in self.jobs}
        self._refs[key] = got  # the latest last
        while len(self._refs) > _SIDES_KEPT:
            self._refs.pop(next(iter(self._refs)))
        return got

    def _waypoint(
        self,
        posed: tuple[Any, Any, dict[str, FloatArray]],
        before: tuple[int, ...] | None,
        jobs: list[Any],
    ) -> dict[str, tuple[FloatArray, dict[str, FloatArray]]]:
        """Each muscle's cage at one waypoint, against its bones from the waypoint ``before``."""
        L, R, out_T = posed
        got = {}
        for j in jobs:
            m = self._prepare()[j.name]
            place = {
                b: invert_rigid(out_T[body]) @ out_T[self.specs[j.name].body]
                for b, body in self.bone_body.items()
            }
            if before is None:
                cage0, place0 = None, self._rest_T[j.name]
            else:
                cage0, place0 = self._nodes[before][j.name]
            sides = sides_at(m.muscle, j, m.in_contact, cage0, place0)
            fallback = m.muscle.cage.C if cage0 is None else cage0
            x, _ = waypoint_cage(j, m.d, m.in_contact, L[j.name], R[j.name], place, sides, fallback)
            got[j.name] = (x, place)
        return got

    def solve(
        self, values: dict[str, float] | None = None, *, frame: int | None = None
    ) -> PoseResult:
        """Deform every muscle at a pose: ``values`` of the driven coordinates, or a frame.

        ``values`` (the motion's units, see `Coordinate`) set the coordinates they
        name; the others stay at the rest pose. ``frame`` (a position in the motion):
        that frame's pose, as the run drives it (a line CSV's scene: frames only).
        """
        with self._lock, self._pools.limit(limits=1, user_api="blas"):
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
            paths, key = self._paths(None)
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
            paths, key = self._paths(pose)
            L, R, out_T = p.at(pose)
        t_path = time.perf_counter()
        ms = self._prepare()
        sides = self._sides(key)
        for j in self.jobs:
            m, path = ms[j.name], paths[j.name]
            m.span = self._span(
                j.name,
                [L[j.name]],
                [R[j.name]],
                out_T,
                None if path is None else (0 if len(path.cages) else -1),
                0.0 if frame is None else float(drive.times[frame]),
                0 if frame is None else int(drive.frames[frame]),
            )
            m.path, m.refs = path, sides[j.name]
        if self.grouped:
            if self._facing is None:
                to_common = {j.name: np.linalg.inv(drive.to_body[j.name]) for j in self.jobs}
                self._facing = facing_at_rest(
                    {n: m.d for n, m in ms.items()}, to_common, cache=self.cache
                )
            results = meet_frame(
                ms, 0, self._facing, self.jobs[0].margin, self.scene.muscle_pairs,
                self.scene.muscle_together,
            )  # fmt: skip
        else:
            results = {n: m.solve_frame(0) for n, m in ms.items()}
        t_solve = time.perf_counter()
        res = self._measure(ms, results, shown, frame, out_T, L)
        res.seconds = {
            "path": t_path - t0,
            "solve": t_solve - t_path,
            "measure": time.perf_counter() - t_solve,
        }
        # each muscle's solver as at this pose (the next pose gives them new spans)
        res.solved = ({n: copy.copy(m) for n, m in ms.items()}, results, out_T)
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
        muscles, stretch, rows, lines, fibres = {}, {}, {}, {}, {}
        for n, m in ms.items():
            r = results[n]
            T = m.span.to_output[0]
            _, depth, _ = m.penetration(r, m.bones_here(0))
            ok = np.isfinite(r.V).all()
            muscles[n] = apply_transform(T, r.V)
            stretch[n] = m.muscle.area_stretch(r.V) if ok else np.full(len(r.V), np.nan)
            lines[n] = [apply_transform(T, np.asarray(P, dtype=np.float64)) for P in L[n].values()]
            if m.fb is not None and ok:
                got = frame_fibres(m.fb, m.muscle.F, r, 0, None, None, m.solve)
                if got["points"] is not None:
                    fibres[n] = apply_transform(T, got["points"].reshape(-1, 3)).reshape(
                        got["points"].shape
                    )
            rows[n] = {
                "relative_volume_error": r.relative_volume_error,
                "penetration_depth_max": depth,
                "muscle_overlap_max": r.muscle_overlap if self.grouped else float("nan"),
                "converged": bool(r.converged),
                "reason": r.reason,
                "iterations": r.iterations,
            }
        bones = {b: out_T[body] for b, body in self.bone_body.items()} if out_T else {}
        return PoseResult(
            shown, frame, muscles, stretch, bones, lines, fibres, rows, pairs=self.pairs
        )  # fmt: skip

    def contact(self, result: PoseResult) -> dict[str, FloatArray]:
        """Each vertex's signed distance to the nearest bone or muscle kept apart from it.

        Exact (mesh units; negative inside), within ``defaults.view_contact_reach`` and capped at
        +-``defaults.view_contact_reach``: to each bone's surface as the run places it (the bone's
        `musclewrap.contact.Obstacle.query`: its grid skips the points beyond the reach,
        the side by pseudo-normals) and to the other muscles of the pose's ``pairs``
        (`musclewrap.contact.muscle_gaps`, the side by winding numbers). The grid's
        trilinear distance, used before, was up to 4.3 mm off on the LHDL walk (a vertex
        0.7 mm from the femur coloured as 5 mm away, where its cell left the grid's exact
        band). Computed when first asked for, then kept in ``result.contact``
        (``benchmarks/speed/bench_view.py SCENE --phases``, BENCHMARKS.md).
        """
        if result.contact is None:
            ms, results, _ = result.solved
            got = muscle_gaps(
                {n: (V, ms[n].muscle.F) for n, V in result.muscles.items()},
                result.pairs,
                defaults.view_contact_reach,
            )
            for n, m in ms.items():
                V = results[n].V
                if not np.isfinite(V).all():
                    continue
                for pl in m.bones_here(0).values():
                    # exact within the reach (the bone's grid skips the points beyond it)
                    idx, phi, _, _ = pl.obstacle.query(
                        pl.to_obstacle(V), defaults.view_contact_reach
                    )
                    got[n][idx] = np.minimum(got[n][idx], phi)
            result.contact = {
                n: np.maximum(g, -defaults.view_contact_reach) for n, g in got.items()
            }
        return result.contact

    def view(self, size: tuple[int, int] | None = None) -> Any:
        """The run's pictures' camera (`._run.picture_view`), for pictures of ``size``."""
        return picture_view(self.scene, self.drive, self.inputs.muscles, size)

    def muscle_faces(self, name: str) -> IntArray:
        """Muscle ``name``'s triangles (as its files have them)."""
        self.prepare()
        return self._built[name].muscle.F  # type: ignore[index,no-any-return]

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

        folder = Path(folder)
        ms, results, out_T = result.solved
        written: list[Path] = []
        for n, m in ms.items():
            w = copy.copy(m)  # the muscle's solver at this pose, writing into ``folder``
            w.out, w.result = folder, ChunkResult(n, [], [])
            w.emit(0, results[n], results[n].muscle_overlap if self.grouped else None)
            written += [folder / f for _, f in w.result.entries]
        for b, (V, F) in self.bone_meshes().items():
            f = folder / b / f"{b}.vtp"
            write_mesh(f, apply_transform(out_T[self.bone_body[b]], V), F)
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

"""Run scenes: every muscle for every frame, written as a ParaView series with a report.

A run goes through four rooms: reading (`._read`: meshes, motion, rest overlap, in
this process), planning (`._plan`: typed tasks), executing (`._execute`: one loop
over one executor interface, in this process, in local worker processes or on a
Dask cluster, `._dask`) and writing (`._write`; the frame files are written by the
tasks themselves). A batch of scenes is one plan over one executor: the per-mesh
reading of the next scene goes to the workers before the last scene's chunks, and
this process drives the motions, plans, and writes each finished scene.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ..constants import UNITS, defaults
from ..errors import SceneError
from ..mesh import apply_transform
from ..model import resample_polyline
from ..output import (
    Pictures,
    PictureTask,
    RenderingError,
    View,
    close_renderer,
    frame_view,
    label_files,
    save_gif,
)
from ..scene import Drive, Scene
from ._dask import DaskExecutor
from ._execute import (
    LATE,
    Executor,
    LocalExecutor,
    Node,
    ProcessExecutor,
    Runner,
    import_plotting_meanwhile,
)
from ._files import GIF
from ._journal import Journal
from ._plan import chunks, frame_span, muscle_jobs, path_span
from ._read import (
    Inputs,
    check_outputs_spare_inputs,
    default_cache_dir,
    read_inputs,
)
from ._records import ChunkResult, Comparison, FrameSpan, MuscleJob, MuscleOutcome
from ._work import Compare, DeformChunk, DeformGroup, FollowPath, Prepare, ProbeBone
from ._write import REPORT_FIELDS, Progress, RunSummary, write_bones, write_outputs

__all__ = [
    "REPORT_FIELDS",
    "RunOptions",
    "RunSummary",
    "default_cache_dir",
    "run_batch",
    "run_scene",
]


@dataclass(frozen=True)
class RunOptions:
    """How a run goes: the options `run_scene` and `run_batch` take, as one record.

    Attributes
    ----------
    frames : str, optional
        ``start:stop:step`` over the motion's rows.
    workers : int
        Processes over muscles and chunks of frames (1: in this process).
    cache_dir : path, True or False
        Where preparations are cached (True: the scene's ``cache_dir`` or
        `default_cache_dir`; False: no cache).
    progress : file-like or None
        Where the progress bar goes.
    render : bool, optional
        Write ``scene.gif`` (default: the scene's ``[output] gif``).
    log : callable, optional
        Receives one-line messages (repairs, notes) as they happen.
    resume : bool
        Go on from an interrupted run into the same output folder: its finished
        frame chunks (recorded in ``OUTDIR/.musclewrap-run``) are kept, the rest
        run; refused if the scene, a file it names or the frames changed. The
        outputs are the same as those of an uninterrupted run.
    collisions : bool, optional
        Keep the muscles out of the scene's bones (default: the scene's
        ``[collisions] enabled``, on whenever it has bones).
    executor : Executor or distributed.Client, optional
        Where the tasks run (default: from ``workers``); a ``dask.distributed``
        client sends them to its cluster (`musclewrap.run.DaskExecutor`).
    """

    frames: str | None = None
    workers: int = 1
    cache_dir: Path | None | bool = True
    progress: Any = sys.stderr
    render: bool | None = None
    log: Callable[[str], None] | None = None
    resume: bool = False
    collisions: bool | None = None
    executor: Executor | Any | None = None


def run_scene(
    scene: Scene, outdir: Path, options: RunOptions | None = None, **kw: Any
) -> RunSummary:
    """Deform every muscle of a scene for every selected frame and write all outputs.

    Parameters
    ----------
    scene : Scene
        From `load_scene`.
    outdir : pathlib.Path
        Output folder (created).
    options : RunOptions, optional
        How the run goes (default: `RunOptions`'s defaults).
    **kw
        Any of `RunOptions`'s fields, in place of those of ``options``
        (``run_scene(scene, out, frames="0:211:10", workers=2)``).

    Returns
    -------
    RunSummary
    """
    return run_batch([scene], [outdir], options, **kw)[0]


def run_batch(
    scenes: Sequence[Scene],
    outdirs: Sequence[Path],
    options: RunOptions | None = None,
    **kw: Any,
) -> list[RunSummary]:
    """Run several scenes as one plan over one executor; one output folder each.

    As `run_scene`, with a scene and an output folder per run (``outdirs``, as many
    as ``scenes``, all different). Each muscle and bone is prepared once for the
    whole batch (scenes that share a mesh share its preparation). Returns a summary
    per scene, in order.
    """
    unknown = sorted(set(kw) - {f.name for f in dataclasses.fields(RunOptions)})
    if unknown:
        known = ", ".join(f.name for f in dataclasses.fields(RunOptions))
        raise TypeError(f"unknown run option(s) {', '.join(unknown)}; RunOptions has {known}")
    o = dataclasses.replace(options or RunOptions(), **kw)
    frames, workers, cache_dir, progress = o.frames, o.workers, o.cache_dir, o.progress
    render, log, resume, collisions, executor = o.render, o.log, o.resume, o.collisions, o.executor
    if len(scenes) != len(outdirs):
        raise ValueError(f"{len(scenes)} scene(s) but {len(outdirs)} output folder(s)")
    dirs = [Path(o).resolve() for o in outdirs]
    if len(set(dirs)) != len(dirs):
        raise ValueError("two runs of the batch would write into the same output folder")
    say = log or (lambda s: None)
    runs = [
        _SceneRun(sc, Path(o), render, collisions) for sc, o in zip(scenes, outdirs, strict=True)
    ]
    for r in runs:
        check_outputs_spare_inputs(r.scene, r.outdir)
    bar = Progress(0, progress) if progress is not None else None
    with contextlib.ExitStack() as stack:
        ex = _executor(executor, workers, sum(len(sc.muscles) for sc in scenes), stack)
        runner = Runner(ex, None if bar is None else bar.add)
        if ex.dashboard:
            say(f"Dask dashboard: {ex.dashboard}")
        temp: list[Path] = []

        def cache_for(scene: Scene) -> Path | None:
            if cache_dir is True:
                return Path(scene.cache_dir or default_cache_dir())
            if cache_dir is not False and cache_dir is not None:
                return Path(cache_dir)
            # no cache: the workers still share what they build, for this batch only
            if not temp:
                where = dirs[0] if ex.remote else None
                if where is not None:
                    where.mkdir(parents=True, exist_ok=True)
                temp.append(
                    Path(
                        stack.enter_context(
                            tempfile.TemporaryDirectory(prefix=".musclewrap-cache-", dir=where)
                        )
                    )
                )
            return temp[0]

        try:
            for i, r in enumerate(runs):
                # at most _AHEAD scenes planned but not written: the main process holds
                # their jobs (meshes, per-frame lines) until then
                while i >= _AHEAD and not runs[i - _AHEAD].finished:
                    runner.poll()
                    _finish_ready(runs, runner)
                cache = cache_for(r.scene)
                # before any task of the scene: its reading tasks write into the cache
                problem = ex.check_shared([r.outdir] + ([] if cache is None else [cache]))
                if problem is not None:
                    raise SceneError(problem)
                r.plan(frames, cache, ex, say, resume, i, bar, runner)
                runner.add(r.nodes)
                r.write_bones()  # while the workers start on its tasks
                runner.add(r.picture_nodes(bar))  # they show the bones too
                runner.poll(0)  # take in what finished meanwhile, submit what it unblocked
                _finish_ready(runs, runner)

            import_plotting_meanwhile()
            while any(not (r.finished and r.drawn) for r in runs):
                runner.poll()
                _finish_ready(runs, runner)
        finally:
            close_renderer()  # this process's, if its tasks ran here
    return [r.summary_at_end() for r in runs]


#: scenes of a batch planned ahead of the oldest one not written yet
_AHEAD = 3


def picture_view(
    scene: Scene,
    drive: Drive,
    muscles: dict[str, tuple[np.ndarray, np.ndarray]],
    size: tuple[int, int] | None = None,
) -> View:
    """A scene's pictures' camera, framed on the muscles through the whole motion.

    Known before any frame is solved, so the pictures are drawn beside the
    deformation: the box round every frame's action lines in the output frame,
    widened by the farthest any muscle's rest mesh (``muscles``, in its body's frame)
    lies from its rest lines; seen as `frame_view` places it, turned by ``[output]
    view``, for pictures of ``size`` (default the scene's ``[output] image_size``).
    """
    pts, reach = [], 0.0
    for spec in scene.muscles:
        rest = drive.rest_lines[spec.name].values()
        length = sum(float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum()) for P in rest)
        samples = np.vstack([resample_polyline(P, length / 200) for P in rest])
        d, _ = cKDTree(samples).query(muscles[spec.name][0])
        reach = max(reach, float(d.max()))
        T = drive.to_output[spec.body]
        for k, lines in enumerate(drive.lines[spec.name]):
            pts += [apply_transform(T[k], np.asarray(P, dtype=np.float64)) for P in lines.values()]
    P = np.vstack(pts)
    return frame_view(
        P.min(axis=0) - reach, P.max(axis=0) + reach, scene.view, size or scene.image_size
    )


def _part(result: Any, name: str) -> ChunkResult:
    """A muscle's chunk: the task's result, or its part of a group's."""
    return result[name] if isinstance(result, dict) else result  # type: ignore[no-any-return]


def _finish_ready(runs: list[_SceneRun], runner: Runner) -> None:
    for r in runs:
        if r.planned and not r.finished and not runner.busy(r.keys):
            r.finish(runner)
        if r.finished and not r.drawn and not runner.busy(r.picture_keys):
            r.write_gif(runner)


def _executor(executor: Any, workers: int, muscles: int, stack: contextlib.ExitStack) -> Executor:
    if executor is not None:
        if isinstance(executor, Executor):
            return executor

        return stack.enter_context(DaskExecutor(executor))  # a distributed.Client
    return local_executor(workers, muscles, stack)


def local_executor(workers: int, muscles: int, stack: contextlib.ExitStack) -> Executor:
    """The executor on this machine for ``muscles`` muscles on ``workers`` processes, entered.

    Worker processes (no more than the muscles) where there are two of each, this
    process otherwise. Started first (a caller may start it before the scene's check):
    the workers import while this process reads meshes and OpenSim.
    """
    if workers > 1 and muscles > 1:
        return stack.enter_context(ProcessExecutor(min(workers, muscles)))
    return LocalExecutor()


@dataclass
class _SceneRun:
    """One scene of a batch: read, planned into nodes, finished (written) when they are."""

    scene: Scene
    outdir: Path
    render: bool | None
    collisions: bool | None
    notes: list[str] = field(default_factory=list)
    nodes: list[Node] = field(default_factory=list)
    keys: list[Any] = field(default_factory=list)
    planned: bool = False
    finished: bool = False
    summary: RunSummary | None = None
    picture_keys: list[Any] = field(default_factory=list)
    grouped: bool = field(init=False, default=False)
    drawn: bool = False  # finished, and its GIF written (or not asked for)
    t0: float = field(default_factory=time.perf_counter)
    cache: Path | None = None
    # set by plan()
    inputs: Inputs = field(init=False)
    jobs: list[Any] = field(init=False)
    journal: Journal = field(init=False)
    prepare_keys: dict[str, Any] = field(init=False)
    path_keys: dict[str, Any] = field(init=False)
    chunk_keys: dict[str, list[Any]] = field(init=False)
    parts: list[range] = field(init=False)
    tag: int = field(init=False)
    bone_entries: list[tuple[int, str]] = field(init=False)
    _view: View | None = field(init=False, default=None)

    def plan(
        self,
        frames: str | None,
        cache: Path | None,
        ex: Executor,
        say: Callable[[str], None],
        resume: bool,
        tag: int,
        bar: Progress | None,
        runner: Runner | None = None,
    ) -> None:
        scene = self.scene
        self.cache = cache
        on = scene.collisions if self.collisions is None else bool(self.collisions and scene.bones)
        # muscles against each other: the muscles of a frame are solved together, in one
        # task per chunk of frames
        self.grouped = (
            self.collisions is not False and scene.muscle_collisions and len(scene.muscles) > 1
        )
        self.inputs = read_inputs(
            scene, frames, cache, on, say, self.notes, runner, muscles_apart=self.grouped
        )
        drive = self.inputs.drive
        self.outdir.mkdir(parents=True, exist_ok=True)
        n = len(drive.frames)
        run = os.urandom(8).hex()  # tells a worker's kept muscle from another run's
        self.jobs = muscle_jobs(self.inputs, self.outdir, run)
        spans = {j.name: frame_span(self.inputs, j.name) for j in self.jobs}
        if self.grouped:
            parts = chunks(n, 1, ex.workers, len(self.jobs))
        else:
            parts = chunks(n, len(self.jobs), ex.workers)
        journal = Journal(self.outdir, self.inputs.key, [(c.start, c.stop) for c in parts], resume)
        self.journal = journal
        self.tag = tag
        self.notes += journal.notes
        parts = self.parts = [range(a, b) for a, b in journal.chunks]
        if bar is not None:
            bar.grow(n * len(self.jobs))
        nodes: list[Node] = []
        # what is not cached yet is built first, spread over the workers, then read back by all
        shared: list[Any] = []
        if cache is not None:
            for b in self.inputs.bones.values():
                if not (cache / b.probe).is_file():
                    nodes.append(
                        Node(("probe", str(cache), b.probe), ProbeBone(b, str(cache)), priority=1)
                    )
                    shared.append(nodes[-1].key)
        self.prepare_keys = {}
        self.path_keys = {}
        group_after: list[Any] = []
        group_kept: list[list[Any]] = []
        for j in self.jobs:
            after = list(shared)
            p = j.prepare_path()
            if p is None or not p.is_file():
                key = ("prepare", str(p), j.name) if p is not None else ("prepare", tag, j.name)
                nodes.append(Node(key, Prepare(j), priority=1))
                after.append(key)
                self.prepare_keys[j.name] = key
            elif (fp := j.fibres_path()) is not None and not fp.is_file():
                key = ("fibres", str(fp))
                nodes.append(Node(key, Prepare(j, fibres_only=True), priority=1))
                after.append(key)
            kept_all = [journal.chunk(j.name, ks.start, ks.stop) for ks in parts]
            path_key = None
            if j.contact is not None and any(k is None for k in kept_all):
                # the muscle at its waypoints, once: where every frame takes its sides
                path_key = self.path_keys[j.name] = (tag, "path", j.name)
                nodes.append(
                    Node(
                        path_key,
                        FollowPath(j, path_span(self.inputs, j.name), self.kept),
                        tuple(after),
                        priority=1,
                    )
                )
            chunk_keys = []
            if self.grouped:
                group_after.extend(a for a in after if a not in group_after)
                if path_key is not None:
                    group_after.append(path_key)
                group_kept.append(kept_all)
                continue
            for ks, kept in zip(parts, kept_all, strict=True):
                key = (tag, "chunk", j.name, ks.start)
                part = spans[j.name].slice(ks.start, ks.stop)
                node = Node(
                    key,
                    DeformChunk(j, part)
                    if path_key is None
                    else self._chunk_task(j, part, path_key),
                    tuple(after) if path_key is None else (*after, path_key),
                    done=self._chunk_done(j.name, ks),
                    frames=len(ks),
                )
                if kept is not None:
                    node.result, node.finished = ChunkResult.from_json(kept), True
                    if bar is not None:
                        bar.skip(len(ks))
                    node.frames = 0
                nodes.append(node)
                chunk_keys.append(key)
            if scene.paper_frames > 0:
                nodes.append(self._compare_node(j, spans[j.name], chunk_keys))
        if self.grouped:
            nodes += self._group_nodes(spans, group_after, group_kept, bar)
        self.nodes = nodes
        self.keys = [nd.key for nd in nodes]
        self.chunk_keys = {
            j.name: [
                (tag, "group", ks.start) if self.grouped else (tag, "chunk", j.name, ks.start)
                for ks in parts
            ]
            for j in self.jobs
        }
        self.planned = True

    def _group_nodes(
        self,
        spans: dict[str, Any],
        after: list[Any],
        kept: list[list[Any]],
        bar: Progress | None,
    ) -> list[Node]:
        """The muscles in contact: a task per chunk of frames with all of them (`DeformGroup`)."""
        tag, jobs, drive = self.tag, tuple(self.jobs), self.inputs.drive
        to_common = tuple(np.linalg.inv(drive.to_body[j.name]) for j in jobs)
        path_keys = [self.path_keys.get(j.name) for j in jobs]
        nodes = []
        keys = []
        for p, ks in enumerate(self.parts):
            key = (tag, "group", ks.start)
            part = tuple(spans[j.name].slice(ks.start, ks.stop) for j in jobs)

            def make(results: dict[Any, Any], part: tuple[Any, ...] = part) -> DeformGroup:
                paths = tuple(None if k is None else results[k] for k in path_keys)
                return DeformGroup(jobs, part, paths, to_common, self.scene.muscle_pairs)

            node = Node(
                key,
                make,
                tuple(after),
                done=self._group_done(ks),
                frames=len(ks) * len(jobs),
            )
            done = [kept[i][p] for i in range(len(jobs))]
            if all(d is not None for d in done):
                node.result = {
                    j.name: ChunkResult.from_json(d) for j, d in zip(jobs, done, strict=True)
                }
                node.finished = True
                if bar is not None:
                    bar.skip(len(ks) * len(jobs))
                node.frames = 0
            nodes.append(node)
            keys.append(key)
        if self.scene.paper_frames > 0:
            nodes += [self._compare_node(j, spans[j.name], keys) for j in jobs]
        return nodes

    @property
    def kept(self) -> int:
        """Muscles a worker keeps bound (`._work._deformer`) for the waypoints and comparisons.

        A group's frames need every muscle in each process: those its waypoints bound
        stay for them, built once, not twice; alone, one at a time.
        """
        return len(self.jobs) if self.grouped else 1

    def _compare_node(self, job: MuscleJob, span: FrameSpan, after: list[Any]) -> Node:
        """The paper's iteration beside the default for one muscle, once its frames are done."""
        node = Node(
            (self.tag, "compare", job.name),
            self._compare_task(job, span, after, self.kept),
            tuple(after),
            done=self._compare_done(job.name),
            priority=3,
        )
        found = self.journal.comparison(job.name)
        if found is not None:
            node.result, node.finished = Comparison.from_json(found), True
        return node

    def _group_done(self, ks: range) -> Callable[[dict[str, ChunkResult]], Any]:
        def done(parts: dict[str, ChunkResult]) -> dict[str, ChunkResult]:
            for name, part in parts.items():
                self.journal.save_chunk(name, ks.start, ks.stop, part.to_json())
            return parts

        return done

    def _chunk_done(self, name: str, ks: range) -> Callable[[ChunkResult], ChunkResult]:
        def done(part: ChunkResult) -> ChunkResult:
            self.journal.save_chunk(name, ks.start, ks.stop, part.to_json())
            return part

        return done

    @staticmethod
    def _chunk_task(
        job: MuscleJob, span: FrameSpan, path_key: Any
    ) -> Callable[[dict[Any, Any]], Any]:
        def make(results: dict[Any, Any]) -> DeformChunk:
            return DeformChunk(job, span, results[path_key])

        return make

    def _compare_done(self, name: str) -> Callable[[Comparison], Comparison]:
        def done(c: Comparison) -> Comparison:
            self.journal.save_comparison(name, c.to_json())
            return c

        return done

    @staticmethod
    def _compare_task(
        job: MuscleJob, span: FrameSpan, chunk_keys: list[Any], keep: int
    ) -> Callable[[dict[Any, Any]], Any]:
        def make(results: dict[Any, Any]) -> Compare:
            rows = [r for k in chunk_keys for r in _part(results[k], job.name).rows]
            worst, solved = Compare.frames_of(rows)
            return Compare(job, span, worst, solved, keep)

        return make

    def write_bones(self) -> None:
        drive = self.inputs.drive
        self.bone_entries = write_bones(
            self.outdir,
            list(self.inputs.bones.values()),
            {b.name: drive.to_output[b.body] for b in self.scene.bones},
            drive.frames,
            self.scene.bone_display_faces,
            self.cache,
        )

    def finish(self, runner: Runner) -> None:
        """The scene's frames are done: its series, report and plots (the GIF may not be)."""
        scene, drive = self.scene, self.inputs.drive
        results = []
        for j in self.jobs:
            parts = [_part(runner.result(k), j.name) for k in self.chunk_keys[j.name]]
            pk = self.prepare_keys.get(j.name)
            # without a preparation task, the path's (the muscle's first task) says how it
            # was had
            path = runner.result(self.path_keys[j.name]) if j.name in self.path_keys else None
            prepared = runner.result(pk) if pk is not None else path and path.prepared
            if path is not None and path.reasons:
                self.notes.append(self._path_note(j.name, path.reasons))
            comparison = (
                runner.result((self.tag, "compare", j.name))
                if scene.paper_frames > 0
                else Comparison()
            )
            results.append(MuscleOutcome.merge(j.name, parts, prepared, comparison))
        order = {s.name: i for i, s in enumerate(scene.muscles)}
        results.sort(key=lambda r: order[r.name])
        rows, files = write_outputs(
            self.outdir,
            scene,
            drive,
            results,
            self.bone_entries,
            self.inputs.contact is not None,
            self.notes,
        )
        self.notes += _conflict_notes(rows, scene.mesh_unit)
        self.notes += _overlap_notes(rows, scene.mesh_unit)
        self.notes += _bone_notes(rows, scene.mesh_unit, _kept_depths(self.inputs.contact))
        worst = max(
            (abs(r["relative_volume_error"]) if np.isfinite(r["relative_volume_error"]) else np.inf)
            for r in rows
        )
        self.summary = RunSummary(
            outdir=self.outdir,
            n_frames=len(drive.frames),
            muscles=[s.name for s in scene.muscles],
            rows=rows,
            worst_volume_error=float(worst),
            unconverged=sum(not r["converged"] for r in rows),
            seconds=0.0,
            seconds_prepare={r.name: r.seconds_prepare for r in results},
            cache_hits=[r.name for r in results if r.cache_hit],
            notes=self.notes,
            files=files,
            view=self.view(),
        )
        self.finished = True

    def _path_note(self, name: str, reasons: list[tuple[int, str]]) -> str:
        """A muscle's waypoints that did not converge: how many, the first one's pose, why."""
        wp = self.inputs.drive.waypoints
        k, why = reasons[0]
        return (
            f"{name}: {len(reasons)} of {len(wp.parent)} waypoints on the path from the rest pose "
            f"did not converge (the frames after them take their sides of the bones from there); "
            f"the first at {wp.describe(k)}: {why}"
        )

    @property
    def draws(self) -> bool:
        """Whether the scene's GIF is drawn."""
        return self.render if self.render is not None else self.scene.gif

    def picture_nodes(self, bar: Progress | None) -> list[Node]:
        """The GIF's pictures, a task per part of the frames, once those frames are written.

        Each waits for the chunks of its frames and of the first frame (whose
        meshes place the camera), so pictures are drawn beside the deformation.
        """
        scene, drive = self.scene, self.inputs.drive
        shown = range(0, len(drive.frames), scene.gif_every)
        if not self.draws or not len(shown):
            self.drawn = True
            return []
        if bar is not None:
            bar.grow_pictures(len(shown))
        # the muscles in the scene's order, as in scene.pvd: their colours follow it
        order = [s.name for s in scene.muscles]
        first = [self.chunk_keys[m][0] for m in order]
        nodes = []
        for p, ks in enumerate(self.parts):
            pictures = [i for i, k in enumerate(shown) if k in ks]
            if not pictures:
                continue
            after = tuple(dict.fromkeys(first + [self.chunk_keys[m][p] for m in order]))
            key = (self.tag, "pictures", ks.start)
            nodes.append(
                Node(
                    key,
                    self._picture_task(pictures, shown, after),
                    after,
                    done=self._pictures_done(bar, len(pictures)),
                    priority=LATE,
                )
            )
            self.picture_keys.append(key)
        return nodes

    def _picture_task(
        self, pictures: list[int], shown: range, after: tuple[Any, ...]
    ) -> Callable[[dict[Any, Any]], PictureTask]:
        scene, drive = self.scene, self.inputs.drive
        bones = tuple(b.name for b in scene.bones)
        order = [s.name for s in scene.muscles]
        view = self.view()

        def make(results: dict[Any, Any]) -> PictureTask:
            files: dict[int, list[str]] = {}
            for k, f in self.bone_entries:
                files.setdefault(k, []).append(f)
            for key in after:  # the scene's order: bones, then each muscle's files
                got = results[key]
                for part in [got[m] for m in order] if isinstance(got, dict) else [got]:
                    for k, f in part.entries:
                        files.setdefault(k, []).append(f)
            colours: dict[str, str] = {}
            label_files(files[0], bones, colours)  # the muscles' colours in the scene's order
            steps = tuple(
                (
                    float(drive.times[shown[i]]),
                    label_files(files[shown[i]], bones, colours, scene.colour),
                )
                for i in pictures
            )
            return PictureTask(
                str(self.outdir.resolve()),
                view,
                steps,
                pictures[0],
                len(shown) // 2,
                scene.image_size,
            )

        return make

    def view(self) -> View:
        """The pictures' camera (`picture_view`), once."""
        if self._view is None:
            self._view = picture_view(self.scene, self.inputs.drive, self.inputs.muscles)
        return self._view

    @staticmethod
    def _pictures_done(bar: Progress | None, n: int) -> Callable[[Pictures], Pictures]:
        def done(p: Pictures) -> Pictures:
            if bar is not None:
                bar.add_pictures(n)  # drawn, or not to be (its error is said once, at the end)
            return p

        return done

    def write_gif(self, runner: Runner) -> None:
        """The pictures are drawn: the GIF and its still, written."""
        assert self.summary is not None
        try:
            self.summary.files += save_gif(
                [runner.result(k) for k in self.picture_keys], self.outdir / GIF
            )
        except (RenderingError, OSError) as exc:
            self.summary.notes.append(f"scene.gif not written: {exc}")
        runner.release(self.picture_keys)  # about 0.5 MB a picture
        self.drawn = True

    def summary_at_end(self) -> RunSummary:
        assert self.summary is not None
        # temporary files of writes whose worker was killed (its task ran again elsewhere)
        stale = [p for p in self.outdir.rglob(".*.part.*") if p.is_file()]
        for p in stale:
            p.unlink(missing_ok=True)
        if stale:
            self.summary.notes.append(
                f"removed {len(stale)} unfinished temporary file(s) of a worker that stopped"
            )
        Journal.finish(self.outdir)  # complete: nothing left to resume
        self.summary.seconds = time.perf_counter() - self.t0
        return self.summary


def _overlap_notes(rows: list[dict[str, Any]], unit: str) -> list[str]:
    """The notes of the muscles left inside another muscle deeper than `defaults.overlap_note_mm`.

    Where the rounds end at their cap (`defaults.muscle_rounds`) with muscles still in
    each other (their lines press them together harder than they can give way), the
    frame converged and its volumes are exact, but a user of the meshes must know it:
    on how many frames, how deep and where (``muscle_overlap_max`` in report.csv).
    """
    out = []
    deep = defaults.overlap_note_mm * 1e-3 / UNITS[unit]  # in mesh units
    for name, n, worst in _frames_over(rows, "muscle_overlap_max", lambda _: deep):
        out.append(
            f"{name}: on {n} frame(s) a vertex stays more than {deep:g} {unit} inside "
            f"another muscle (up to {worst['muscle_overlap_max']:.3g} {unit}, frame "
            f"{worst['frame']}, after {worst.get('muscle_rounds', 0)} rounds; "
            "muscle_overlap_max in report.csv): the muscles could not be taken apart there"
        )
    return out


def _frames_over(
    rows: list[dict[str, Any]], key: str, limit: Callable[[str], float | None]
) -> list[tuple[str, int, dict[str, Any]]]:
    """The muscles whose ``key`` passes ``limit(muscle)`` on some frame, in the rows' order.

    Each with on how many frames and the worst frame's row. A limit of None: not looked at.
    """
    out = []
    for name in dict.fromkeys(r["muscle"] for r in rows):
        at = limit(name)
        if at is None:
            continue
        mine = [r for r in rows if r["muscle"] == name and r.get(key, np.nan) > at]
        if mine:
            out.append((name, len(mine), max(mine, key=lambda r: r[key])))
    return out


def _kept_depths(contact: dict[str, dict[str, Any]] | None) -> dict[str, float]:
    """Per muscle that keeps a rest overlap with a bone, how deep it may stay (mesh units)."""
    out = {}
    for name, bones in (contact or {}).items():
        kept = [float(-a.min()) for a in bones.values() if a is not None]
        if kept:
            out[name] = max(max(kept), 0.0)
    return out


def _bone_notes(
    rows: list[dict[str, Any]], unit: str, kept: dict[str, float] | None = None
) -> list[str]:
    """The notes of the muscles the bones' contact left out of its bounds on some frame.

    A vertex deeper than `defaults.bone_note_mm` inside a bone (``penetration_depth_max``
    in report.csv), or a bone's vertex deeper than `defaults.bone_inside_note_mm` inside
    the muscle (``bone_inside_depth_max``): where the finish could not take them apart
    (a pose far past anatomy, a bone the muscles are pressed through). The frame
    converged and its volume is exact, but a user of the meshes must know it. A muscle
    that keeps its rest overlap (``kept``: how deep it may stay, mesh units) is named
    where it goes that much deeper than it was; the bone standing in it, as it did at
    rest, is not (its own note says the overlap was kept).
    """
    kept = kept or {}
    out = []
    for key, mm, what in (
        ("penetration_depth_max", defaults.bone_note_mm, "a vertex stays more than {} inside a bone"),
        ("bone_inside_depth_max", defaults.bone_inside_note_mm, "a bone stands more than {} inside it"),
    ):  # fmt: skip
        deep = mm * 1e-3 / UNITS[unit]  # in mesh units
        inside = key == "penetration_depth_max"

        def limit(name: str, deep: float = deep, inside: bool = inside) -> float | None:
            if name not in kept:
                return deep
            return kept[name] + deep if inside else None  # the bone stands in it as at rest

        for name, n, worst in _frames_over(rows, key, limit):
            more = (
                f" beyond its kept rest overlap ({kept[name]:.3g} {unit})" if name in kept else ""
            )
            out.append(
                f"{name}: on {n} frame(s) " + what.format(f"{deep:g} {unit}") + more
                + f" (up to {worst[key]:.3g} {unit}, frame {worst['frame']}; {key} in "
                "report.csv): the bones' contact could not be met there"
            )  # fmt: skip
    return out


def _conflict_notes(rows: list[dict[str, Any]], unit: str) -> list[str]:
    """The notes of the muscles whose lines ran inside a bone (contact wins over the lines).

    On how many frames, how deep, and how far the surface, kept out of the bone, left
    them there; and how well it followed them where they lie outside the bones.
    """
    out = []
    deep = defaults.line_conflict_mm * 1e-3 / UNITS[unit]  # in mesh units
    for name in dict.fromkeys(r["muscle"] for r in rows):
        mine = [
            r
            for r in rows
            if r["muscle"] == name
            and r.get("lines_conflict_max", 0) > 0
            and r["line_inside_depth_max"] > deep
        ]
        if not mine:
            continue
        worst = max(mine, key=lambda r: r["lines_conflict_max"])
        free = [r.get("skeleton_fit_free", np.nan) for r in rows if r["muscle"] == name]
        out.append(
            f"{name}: on {len(mine)} frame(s) its lines run more than {deep:g} {unit} inside a "
            f"bone (up to "
            f"{max(r['line_inside_depth_max'] for r in mine):.3g} {unit} deep); contact wins "
            f"there: the surface leaves them by up to {worst['lines_conflict_max']:.3g} {unit} "
            f"(frame {worst['frame']}; lines_conflict_max in report.csv); where the lines lie "
            f"outside the bones it follows them to {np.nanmax(free):.3g} {unit} "
            "(skeleton_fit_free, the worst frame's mean)"
        )
    return out

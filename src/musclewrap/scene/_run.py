"""Run a scene: every muscle for every frame, written as a ParaView series with a report."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._cache import cached_arrays, digest
from .._paths import overwrite_clash
from .._typing import FloatArray, IntArray
from ..contact import Obstacle
from ..mesh import check_mesh, clean_mesh, read_mesh, tidy_mesh, vertex_origins, write_mesh
from ._config import Scene
from ._drive import Drive, apply, drive_scene, invert_rigid
from ._errors import SceneError
from ._fibres import (
    FIBRES_CSV,
    MOMENT_ARMS_CSV,
    PLOT_MOMENT_ARMS,
    fibres_key,
    fibres_of,
    frame_fibres,
    write_fibre_outputs,
    write_frame_fibres,
)
from ._journal import JOURNAL, Journal

__all__ = ["REPORT_FIELDS", "RunSummary", "default_cache_dir", "run_scene"]

#: columns of ``report.csv`` (the first eight are the documented contract)
REPORT_FIELDS = [
    "frame",
    "time",
    "muscle",
    "iterations",
    "converged",
    "relative_volume_error",
    "skeleton_fit_mean",
    "seconds",
    "shape_change_max",
    "penetration_share",
    "penetration_depth_max",
    "contact_vertices",
    "penetration_depth_before",
    "reason",
]


# the files a run writes at the top of its output folder (besides one folder per muscle and bone)
PVD, REPORT, GIF = "scene.pvd", "report.csv", "scene.gif"
PLOT_VOLUME, PLOT_CONVERGENCE = "volume_error.png", "convergence.png"
PLOT_PENETRATION = "penetration.png"
# (render_series also writes the GIF's middle picture beside it, as .png)
_TOP_FILES = (
    PVD,
    REPORT,
    GIF,
    Path(GIF).with_suffix(".png").name,
    PLOT_VOLUME,
    PLOT_CONVERGENCE,
    PLOT_PENETRATION,
    FIBRES_CSV,
    MOMENT_ARMS_CSV,
    PLOT_MOMENT_ARMS,
    JOURNAL,
)


def default_cache_dir() -> Path:
    """``$MUSCLEWRAP_CACHE``, else ``$XDG_CACHE_HOME/musclewrap``, else ``~/.cache/musclewrap``."""
    env = os.environ.get("MUSCLEWRAP_CACHE")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return Path(xdg if xdg else Path.home() / ".cache") / "musclewrap"


@dataclass
class RunSummary:
    """What a run did (printed at the end and returned to Python callers)."""

    outdir: Path
    n_frames: int
    muscles: list[str]
    rows: list[dict[str, Any]]
    worst_volume_error: float
    unconverged: int
    seconds: float
    seconds_prepare: dict[str, float]
    cache_hits: list[str]
    notes: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)

    def text(self) -> str:
        """Human-readable summary."""
        solved = [r for r in self.rows if np.isfinite(r["relative_volume_error"])]
        failed = len(self.rows) - len(solved)

        def worst(key: str) -> float:  # over the frames with positions
            return max((abs(r[key]) for r in solved), default=float("nan"))

        lines = [
            f"{len(self.muscles)} muscle(s) x {self.n_frames} frame(s) in {self.seconds:.1f} s "
            f"-> {self.outdir / PVD}",
            f"  worst |relative volume error| {worst('relative_volume_error'):.2e}; "
            f"unconverged frames {self.unconverged}"
            + (f" ({failed} without positions, no mesh written)" if failed else "")
            + f"; skeleton fit mean <= {worst('skeleton_fit_mean'):.3g}; "
            f"shape change <= {worst('shape_change_max'):.3g} edge lengths; deepest bone "
            f"penetration {worst('penetration_depth_max'):.3g}"
            + (
                f" (without contact {worst('penetration_depth_before'):.3g}; up to "
                f"{max((r['contact_vertices'] for r in solved), default=0)} contact vertices)"
                if any(r["contact_vertices"] for r in solved)
                else ""
            ),
            "  preparation: "
            + ", ".join(
                f"{m} {'cached' if m in self.cache_hits else f'{s:.2f} s'}"
                for m, s in self.seconds_prepare.items()
            ),
        ]
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


# ---------------------------------------------------------------------------- workers
_progress_queue: Any = None
_probes: dict[tuple[str, str | None], Any] = {}
_deformers: dict[tuple[Any, ...], Any] = {}
_fibres_kept: dict[tuple[Any, ...], Any] = {}


def _init_worker(queue: Any, threads: int) -> None:
    global _progress_queue
    _progress_queue = queue
    # A failing initializer breaks the whole pool: thread limits are best effort.
    try:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
        from threadpoolctl import threadpool_limits

        threadpool_limits(threads)
    except Exception:  # pragma: no cover  # noqa: BLE001
        pass


def _tick(n: int = 1) -> None:
    if _progress_queue is not None:
        _progress_queue.put(n)


def _cache_key(V: FloatArray, F: IntArray, job: dict[str, Any]) -> str:
    from ..solver._muscle import _FORMAT

    return digest(
        np.asarray(V, dtype=np.float64),
        np.asarray(F, dtype=np.int64),
        np.asarray(job["input_id"], dtype=np.int64),
        f"{job['cage_size']}|{job['cage_coarsening']}|{_FORMAT}|{__version__}",
    )[:32]


def _prepare_path(job: dict[str, Any]) -> Path | None:
    cache = job["cache_dir"]
    if cache is None:
        return None
    return Path(cache) / f"{job['name']}-{_cache_key(job['V'], job['F'], job)}.npz"


def _prepare(job: dict[str, Any]) -> tuple[Any, bool, str | None]:
    from ..solver import Muscle

    V, F, name = job["V"], job["F"], job["name"]
    path = _prepare_path(job)
    if path is not None:
        if path.is_file():
            try:
                # the name is the hash of the input mesh and settings; load() checks the content
                return Muscle.load(path), True, None
            except ValueError as exc:
                note = f"{name}: cached preparation unusable ({exc}): rebuilt"
        else:
            note = None
    else:
        note = None
    m = Muscle.from_mesh(
        V,
        F,
        cage_size=job["cage_size"],
        cage_coarsening=job["cage_coarsening"],
        source=job["source"],
        cleaned=True,  # by _read_muscle, and only moved rigidly since
        input_id=job["input_id"],
    )
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            m.save(path)
        except OSError as exc:
            note = f"{name}: could not write the cache {path} ({exc.strerror})"
    return m, False, note


def _bone_probe(V: FloatArray, F: IntArray, name: str, cache: str | None) -> Any:
    """The bone's probe (``name``: its `Obstacle.cache_name`): kept per process, cached."""
    from ..contact import Obstacle

    key = (name, cache)
    if key not in _probes:
        _probes[key] = Obstacle.cached(V, F, None if cache is None else Path(cache), name=name)
    return _probes[key]


def _fill_cache(task: tuple[str, Any]) -> dict[str, Any] | None:
    """Phase one of a run in workers: one preparation or bone probe into the cache.

    For a muscle, what its preparation reports (the later jobs read it from the cache).
    """
    kind, arg = task
    if kind == "fibres":  # the muscle is prepared (cached) already
        muscle, _, _ = _prepare(arg)
        fibres_of(muscle, arg, _fibres_path(arg))
        return None
    if kind == "muscle":
        t0 = time.perf_counter()
        muscle, hit, note = _prepare(arg)
        if arg["fibres"] is not None:
            fibres_of(muscle, arg, _fibres_path(arg))
        return {
            "name": arg["name"],
            "seconds_prepare": time.perf_counter() - t0,
            "cache_hit": hit,
            "note": note,
        }
    _bone_probe(*arg)
    return None


def _deformer(job: dict[str, Any]) -> tuple[Any, Any, bool, str | None, float]:
    """The muscle bound to its rest lines, kept per process (a job comes in chunks)."""
    key = (job["name"], job["run"])
    if key in _deformers:
        muscle, d = _deformers[key]
        return muscle, d, True, None, 0.0
    t0 = time.perf_counter()
    muscle, hit, note = _prepare(job)
    seconds = time.perf_counter() - t0
    d = muscle.bind(
        job["rest_lines"], reference_point=job["rest_reference"], anchors=job.get("anchors")
    )
    _deformers.clear()  # one muscle at a time is enough
    _deformers[key] = (muscle, d)
    return muscle, d, hit, note, seconds


def _fibres_path(job: dict[str, Any]) -> Path | None:
    cache = job["cache_dir"]
    if cache is None or job["fibres"] is None:
        return None
    key = fibres_key(_cache_key(job["V"], job["F"], job), job)
    return Path(cache) / f"fibres-{job['name']}-{key}.npz"


def _fibres(job: dict[str, Any], muscle: Any) -> tuple[Any, str | None]:
    """The muscle's fibres (None without a ``[fibres]`` table), kept per process."""
    if job["fibres"] is None:
        return None, None
    key = (job["name"], job["run"])
    if key not in _fibres_kept:
        _fibres_kept.clear()
        _fibres_kept[key] = fibres_of(muscle, job, _fibres_path(job))
    return _fibres_kept[key]  # type: ignore[no-any-return]


_PER_FRAME = ("frames", "times", "lines", "references", "to_output")
_PER_FRAME_MA = ("ma_lines", "ma_references", "ma_to_output")


def _slice(job: dict[str, Any], ks: range) -> dict[str, Any]:
    """The job for frames ``ks`` only (what a worker needs of a chunk)."""
    keys = _PER_FRAME + (_PER_FRAME_MA if job.get("ma") is not None else ())
    part = {**job, **{k: job[k][ks.start : ks.stop] for k in keys}, "offset": ks.start}
    part["bones"] = [(V, F, T[ks.start : ks.stop], *rest) for V, F, T, *rest in job["bones"]]
    if job.get("ma") is not None:
        part["ma_bone_T"] = {b: T[ks.start : ks.stop] for b, T in job["ma_bone_T"].items()}
    return part


def _frames_job(job: dict[str, Any]) -> dict[str, Any]:
    """Deform one muscle on the frames of a `_slice` of its job and write them."""
    from ..conditions import LineError
    from ..solver import DeformationResult, Placed

    muscle, d, hit, note, seconds_prepare = _deformer(job)
    probes = [
        (_bone_probe(V, F, key, job["cache_dir"]), T, bname) for V, F, T, key, bname in job["bones"]
    ]
    contact = job["contact"]  # None (no collisions), or {bone: allowance or None}
    out = Path(job["outdir"])
    name = job["name"]
    rows, entries, fibres = [], [], []
    fb, fibre_note = _fibres(job, muscle)
    kw: dict[str, Any] = {"method": job["method"], "max_iterations": job["max_iterations"]}
    if contact is not None:
        kw["margin"] = job["margin"]

    def solve(
        lines: dict[str, FloatArray],
        reference: FloatArray | None,
        T: FloatArray,
        bone_T: dict[str, FloatArray],
        finish: bool = True,
        bones: bool = True,
    ) -> Any:
        # the scene's bones where contact is on (and ``bones``), else none
        obstacles = (
            [
                # muscle's body frame -> bone's body frame in one transform
                Placed(probe, invert_rigid(bone_T[bname]) @ T, contact[bname], bname)
                for probe, _, bname in probes
                if bname in contact
            ]
            if contact is not None and bones
            else None
        )
        try:
            return d.deform(
                lines, reference_point=reference, finish=finish, obstacles=obstacles, **kw
            )
        except LineError as exc:
            # this pose's lines cannot drive the muscle (e.g. a path collapsed to a point):
            # the frame is reported as failed and the motion goes on
            return DeformationResult.failed(
                len(muscle.V),
                len(muscle.cage.C),
                muscle.volume_rest,
                f"invalid action lines in this frame: {exc}",
            )

    for k in range(len(job["frames"])):
        frame = job["frames"][k]
        T = job["to_output"][k]
        res = solve(job["lines"][k], job["references"][k], T, {b: TB[k] for _, TB, b in probes})
        ok_values = np.isfinite(res.V).all()
        shape = float(muscle.shape_change(res.V).max()) if ok_values else float("nan")
        n_in, depth = (0, 0.0) if ok_values else (float("nan"), float("nan"))
        if ok_values:
            Vo = apply(T, res.V)
            if contact is not None:
                # the contact finish counted its bones exactly
                n_in, depth = res.penetration_vertices, res.penetration_depth
            for probe, TB, bname in probes:
                if contact is not None and bname in contact:
                    continue
                n, dep = probe.measure(apply(invert_rigid(TB[k]) @ T, res.V))
                n_in += n
                depth = max(depth, dep)
            fname = f"{name}/{name}_{frame:04d}.vtp"
            write_mesh(out / fname, Vo, muscle.F, point_data={"input_id": muscle.input_id})
            entries.append((job["offset"] + k, fname))
        lname = f"{name}/{name}_lines_{frame:04d}.vtp"
        P, segs, o = [], [], 0
        for pts in job["lines"][k].values():
            Pp = apply(T, np.asarray(pts, dtype=np.float64))
            P.append(Pp)
            segs += [[o + i, o + i + 1] for i in range(len(Pp) - 1)]
            o += len(Pp)
        write_mesh(out / lname, np.vstack(P), np.zeros((0, 3), int), lines=np.array(segs))
        entries.append((job["offset"] + k, lname))
        if fb is not None:
            got = frame_fibres(fb, muscle.F, res, k, job, solve)
            if got["points"] is not None:
                fname = f"{name}/{name}_fibres_{frame:04d}.vtp"
                write_frame_fibres(out / fname, fb, got["points"], T)
                entries.append((job["offset"] + k, fname))
            fibres.append(
                {
                    "frame": int(frame),
                    "time": float(job["times"][k]),
                    "lengths": got["lengths"].tolist(),
                    "moment_arms": got["moment_arms"].tolist(),
                    "unconverged": got["unconverged"],
                    "moved": got["moved"],
                    "farthest": got["farthest"],
                    "left": got["left"],
                }
            )
        rows.append(
            {
                "frame": int(frame),
                "time": float(job["times"][k]),
                "muscle": name,
                "iterations": res.iterations,
                "converged": res.converged,
                "relative_volume_error": res.relative_volume_error,
                "skeleton_fit_mean": res.skeleton_fit_mean,
                "seconds": res.seconds,
                "shape_change_max": shape,
                "penetration_share": n_in / len(muscle.V),
                "penetration_depth_max": depth,
                "contact_vertices": res.contact_vertices,
                "penetration_depth_before": (
                    res.penetration_depth_before if contact is not None else depth
                ),
                "reason": res.reason,
            }
        )
        _tick()
    return {
        "name": name,
        "rows": rows,
        "entries": entries,
        "fibres": fibres,
        "seconds_prepare": seconds_prepare,
        "cache_hit": hit,
        "note": "; ".join(n for n in (note, fibre_note) if n) or None,
    }


def _comparison_frames(rows: list[dict[str, Any]]) -> tuple[int | None, list[int]]:
    """The frames solved (with positions) and the worst of them.

    The worst has the most iterations, then the largest volume error; None when
    no frame was solved.
    """
    solved = [k for k, r in enumerate(rows) if np.isfinite(r["relative_volume_error"])]
    worst = max(
        solved,
        key=lambda k: (rows[k]["iterations"], abs(rows[k]["relative_volume_error"])),
        default=None,
    )
    return worst, solved


def _compare_job(job: dict[str, Any], frames: tuple[int | None, list[int]]) -> dict[str, Any]:
    """The paper's iteration beside the default on a few frames and the worst one.

    ``frames`` is `_comparison_frames` of the muscle's rows. The worst frame's
    iteration histories (the default's iteration with the fine gradient, method
    "exact", and the paper's) go into convergence.png.
    """
    worst, solved = frames
    if worst is None:
        return {"name": job["name"], "paper": [], "worst_frame": None, "convergence": {}}
    _, d, *_ = _deformer(job)
    spread = np.linspace(0, len(solved) - 1, job["paper_frames"]).round().astype(int)
    picks = {solved[i] for i in spread.tolist()}
    paper, conv = [], {}
    for k in sorted(picks | {worst}):
        r = d.deform(job["lines"][k], reference_point=job["references"][k], method="paper")
        paper.append((int(job["frames"][k]), r.relative_volume_error, r.iterations, r.seconds))
        if k == worst:
            conv["paper"] = [tuple(h) for h in r.history]
    r = d.deform(job["lines"][worst], reference_point=job["references"][worst], method="exact")
    conv["exact"] = [tuple(h) for h in r.history]
    return {
        "name": job["name"],
        "paper": paper,
        "worst_frame": int(job["frames"][worst]),
        "convergence": conv,
    }


def _merge(job: dict[str, Any], parts: list[dict[str, Any]]) -> dict[str, Any]:
    """One muscle's result from its frame chunks (in frame order)."""
    first = parts[0]
    return {
        "name": job["name"],
        "rows": [r for p in parts for r in p["rows"]],
        "entries": [e for p in parts for e in p["entries"]],
        "fibres": [f for p in parts for f in p.get("fibres", [])],
        "seconds_prepare": first["seconds_prepare"],
        "cache_hit": first["cache_hit"],
        "note": next((p["note"] for p in parts if p["note"]), None),
        "paper": [],
        "worst_frame": None,
        "convergence": {},
    }


# ---------------------------------------------------------------------------- progress
class _Progress:
    def __init__(self, total: int, stream: Any) -> None:
        self.total, self.done, self.stream = total, 0, stream
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self._last = -1

    def add(self, n: int) -> None:
        self.done += n
        pct = int(100 * self.done / max(self.total, 1))
        if self.tty:
            bar = "#" * (pct // 4)
            self.stream.write(
                f"\r[{bar:<25}] {self.done}/{self.total} frames x muscles "
                f"{time.perf_counter() - self.t0:5.1f} s"
            )
            if self.done >= self.total:
                self.stream.write("\n")
        elif pct // 10 != self._last // 10:
            self.stream.write(f"{pct:3d}% ({self.done}/{self.total} frames x muscles)\n")
        self._last = pct
        self.stream.flush()


# ---------------------------------------------------------------------------- main
def _decimate(V: FloatArray, F: IntArray, faces: int) -> tuple[FloatArray, IntArray]:
    import pyvista as pv

    cells = np.hstack([np.full((len(F), 1), 3), F]).ravel()
    d = pv.PolyData(V, cells).decimate(1.0 - faces / len(F))
    if not d.n_cells:
        return V, F
    G = d.faces.reshape(-1, 4)[:, 1:]
    return np.asarray(d.points, dtype=np.float64), np.ascontiguousarray(G, dtype=np.int64)


def _bone_display(
    V: FloatArray, F: IntArray, faces: int, cache: Path | None
) -> tuple[FloatArray, IntArray]:
    """A lighter copy of a bone for display (VTK quadric decimation; copes with defects).

    Decimating a 90K-face bone takes about a second, the same every run: the result is
    kept in the preparation cache.
    """
    if faces == 0 or len(F) <= faces:
        return V, F
    path = None if cache is None else cache / f"bone-{digest(V, F, str(faces))[:32]}.npz"

    def build() -> dict[str, np.ndarray]:
        DV, DF = _decimate(V, F, faces)
        return {"V": DV, "F": DF}

    d = cached_arrays(path, build)
    return d["V"], d["F"]


def _cached_mesh(
    path: Path, cache: Path | None, tag: str, build: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    """Arrays `build` makes from a mesh file, cached by the file's bytes and ``tag``."""
    key = digest(path.read_bytes(), f"{tag}|{__version__}|first-appearance order")
    return cached_arrays(None if cache is None else cache / f"mesh-{key[:32]}.npz", build)


def _read_muscle(spec: Any, cache: Path | None) -> tuple[FloatArray, IntArray, list[str], IntArray]:
    """Read and clean (or repair) a muscle mesh; cached.

    Returns the mesh, the notes, and each vertex's index in the file (``input_id``,
    `musclewrap.mesh.vertex_origins`).
    """

    def build() -> dict[str, np.ndarray]:
        V0, F0 = read_mesh(spec.mesh)
        V, F, notes = clean_mesh(V0, F0, source=str(spec.mesh), repair=spec.repair)
        ids = vertex_origins(V0, V)
        return {"V": V, "F": F, "notes": np.array(notes, dtype=str), "input_id": ids}

    d = _cached_mesh(
        spec.mesh,
        cache,
        f"muscle|{spec.repair}|self-intersection, fans, orientation, input_id",
        build,
    )
    return d["V"], d["F"], [str(n) for n in d["notes"]], d["input_id"]


def _read_bone(path: Path, cache: Path | None) -> tuple[FloatArray, IntArray, bool, int]:
    """Read, tidy and orient outward a bone mesh (not required to be manifold); cached.

    Returns the vertices, the faces, whether they were flipped, and the number of
    boundary edges (an open bone: contact has to close it).
    """

    def build() -> dict[str, np.ndarray]:
        V, F, _ = tidy_mesh(*read_mesh(path))
        check = check_mesh(V, F)
        flip = check.volume < 0
        return {
            "V": V,
            "F": F[:, ::-1].copy() if flip else F,
            "flipped": np.array(flip),
            "boundary_edges": np.array(check.boundary_edges),
        }

    d = _cached_mesh(path, cache, "bone|boundary edges", build)
    return d["V"], d["F"], bool(d["flipped"]), int(d["boundary_edges"])


def _closed_bone(
    b: Any,
    V: FloatArray,
    F: IntArray,
    boundary_edges: int,
    cache: Path | None,
    say: Callable[[str], None],
    notes: list[str],
) -> tuple[FloatArray, IntArray]:
    """A bone that contact can use: closed (an open one is repaired, or refused); cached.

    Contact needs an inside: a bone with holes is closed by PyMeshFix, as a muscle is, and
    the run says so; one that cannot be is refused, naming the file.
    """
    from ..contact import bone_surface
    from ..mesh import MeshError

    if not boundary_edges:
        return V, F

    def build() -> dict[str, np.ndarray]:
        try:
            RV, RF, rnotes = bone_surface(V, F, source=str(b.mesh), close=True)
        except MeshError as exc:
            raise SceneError(
                f"{b.mesh}: the bone '{b.name}' is open ({boundary_edges} boundary "
                f"edges) and could not be closed ({exc}); contact needs its inside: close it, "
                "leave it out of the muscles' bones, or set [collisions] enabled = false"
            ) from None
        return {"V": RV, "F": RF, "notes": np.array(rnotes, dtype=str)}

    d = _cached_mesh(b.mesh, cache, "bone-closed", build)
    for n in (str(x) for x in d["notes"]):
        notes.append(f"{b.name}: {n}")
        say(f"{b.name}: {n}")
    return d["V"], d["F"]


def run_scene(
    scene: Scene,
    outdir: Path,
    *,
    frames: str | None = None,
    workers: int = 1,
    cache_dir: Path | None | bool = True,
    progress: Any = sys.stderr,
    render: bool | None = None,
    log: Callable[[str], None] | None = None,
    resume: bool = False,
    collisions: bool | None = None,
) -> RunSummary:
    """Deform every muscle of a scene for every selected frame and write all outputs.

    Parameters
    ----------
    scene : Scene
        From `load_scene`.
    outdir : pathlib.Path
        Output folder (created).
    frames : str, optional
        ``start:stop:step`` over the motion's rows.
    workers : int, optional
        Processes over muscles (1: in this process).
    cache_dir : path, True or False, optional
        Where preparations are cached (True: the scene's ``cache_dir`` or
        `default_cache_dir`; False: no cache).
    progress : file-like or None, optional
        Where the progress bar goes.
    render : bool, optional
        Write ``scene.gif`` (default: the scene's ``[output] gif``).
    log : callable, optional
        Receives one-line messages (repairs, notes) as they happen.
    resume : bool, optional
        Go on from an interrupted run into the same ``outdir``: its finished
        frame chunks (recorded in ``outdir/.musclewrap-run``) are kept, the rest
        run; refused if the scene, a file it names or the frames changed. The
        outputs are the same as those of an uninterrupted run with the same
        number of workers.
    collisions : bool, optional
        Keep the muscles out of the scene's bones (default: the scene's
        ``[collisions] enabled``, on whenever it has bones).

    Returns
    -------
    RunSummary
    """
    t0 = time.perf_counter()
    say = log or (lambda s: None)
    outdir = Path(outdir)
    _check_outputs_spare_inputs(scene, outdir)
    notes: list[str] = []
    with contextlib.ExitStack() as stack:
        pool = None
        if workers > 1 and len(scene.muscles) > 1:
            # started first: the workers import while this process reads meshes and OpenSim
            pool = stack.enter_context(_Pool(min(workers, len(scene.muscles))))
        on = scene.collisions if collisions is None else bool(collisions and scene.bones)
        draw = render if render is not None else scene.gif
        rendering: list[Any] = []

        def start_render() -> None:
            # the frames are written: the renderers start while this process draws the plots
            # (started with the run instead, their start-up slowed the run more: 1.45-1.47x
            # against 1.37x for the walk with its GIF, benchmarks/bench_gif.py)
            from ..output import start_rendering

            try:
                r = start_rendering(
                    outdir / PVD,
                    outdir / GIF,
                    every=scene.gif_every,
                    size=scene.image_size,
                    bones=tuple(b.name for b in scene.bones),
                    progress=progress,
                )
            except OSError as exc:
                notes.append(f"scene.gif not written: {exc}")
                return
            r.go()
            rendering.append(r)

        try:
            summary = _run_scene(
                scene, outdir, frames, pool, cache_dir, progress, say, notes, stack, resume, on,
                start_render if draw else None,
            )  # fmt: skip
        except BaseException:
            for r in rendering:
                r.cancel()
            raise
    for r in rendering:
        try:
            summary.files.append(r.finish())
        except (RuntimeError, OSError) as exc:
            summary.notes.append(f"scene.gif not written: {exc}")
    Journal.finish(outdir)  # complete: nothing left to resume
    summary.seconds = time.perf_counter() - t0
    return summary


def _run_scene(
    scene: Scene,
    outdir: Path,
    frames: str | None,
    pool: _Pool | None,
    cache_dir: Path | None | bool,
    progress: Any,
    say: Callable[[str], None],
    notes: list[str],
    stack: contextlib.ExitStack,
    resume: bool,
    collisions: bool,
    frames_written: Callable[[], None] | None = None,
) -> RunSummary:
    if cache_dir is True:
        cache = scene.cache_dir or default_cache_dir()
    elif cache_dir is False or cache_dir is None:
        cache = None
    else:
        cache = Path(cache_dir)
    # meshes (mesh units, mesh coordinates)
    muscles = {}
    input_ids: dict[str, IntArray] = {}
    for spec in scene.muscles:
        V, F, mnotes, input_ids[spec.name] = _read_muscle(spec, cache)
        for n in mnotes:
            notes.append(f"{spec.name}: {n}")
            say(f"{spec.name}: {n}")
        muscles[spec.name] = (V, F)
    bones = {}
    for b in scene.bones:
        V, F, flipped, open_edges = _read_bone(b.mesh, cache)
        if flipped:
            notes.append(f"{b.name}: faces were oriented inward: flipped")
        if collisions:
            V, F = _closed_bone(b, V, F, open_edges, cache, say, notes)
        bones[b.name] = (V, F)
    centroids = {n: V.mean(axis=0) for n, (V, _) in bones.items()}
    drive = drive_scene(scene, frames, centroids)
    notes += drive.notes
    # every mesh in the frame of the body that carries it
    muscles = {m: (apply(drive.to_body[m], V), F) for m, (V, F) in muscles.items()}
    bones = {b: (apply(drive.to_body[b], V), F) for b, (V, F) in bones.items()}
    _check_units(scene, drive, muscles)
    if cache is None and pool is not None:
        # the workers still share what they build, for this run only
        cache = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="musclewrap-")))
    contact = anchors = None
    if collisions:
        muscles, contact, anchors = _rest_overlap(scene, drive, muscles, bones, cache, say, notes)
    key = _run_key(scene, drive, collisions)
    return _run(
        scene,
        outdir,
        drive,
        muscles,
        bones,
        cache,
        pool,
        progress,
        notes,
        key,
        resume,
        contact,
        anchors,
        input_ids,
        frames_written,
    )


def _push_out_rest(
    V: FloatArray, F: IntArray, placed: list[Any], margin: float, cache: Path | None
) -> tuple[FloatArray | None, Any, str]:
    """The rest pose's push-out (cached): with the bone vertices, else without, else none.

    Taking the bones' vertices out of the muscle as well (`push_out` with
    ``bone_vertices``) costs seconds and can fold the surface where a bone's
    edge is thin: a result whose surface passes through itself is not used.
    Returns the positions (None: every variant folded), the report and which
    variant was used.
    """
    from ..mesh import self_intersecting_faces, volume
    from ..solver import ContactReport, push_out

    key = digest(
        V,
        F,
        *(np.asarray(pl.T) for pl in placed),
        "|".join(Obstacle.cache_name(pl.obstacle.V, pl.obstacle.F) for pl in placed),
        f"{margin}|{__version__}|rest-overlap",
    )
    path = None if cache is None else cache / f"rest-{key[:32]}.npz"
    done: list[Any] = []

    def build() -> dict[str, np.ndarray]:
        rep = None
        for how in ("bone vertices", "vertices"):
            P, rep = push_out(
                V, F, placed, volume_target=volume(V, F), margin=margin,
                bone_vertices=how == "bone vertices",
            )  # fmt: skip
            if rep.rounds == 0 or not rep.ok or self_intersecting_faces(P, F) == 0:
                done.append((P, rep, how))
                break
        else:
            done.append((None, rep, "none"))
        P, rep, how = done[0]
        return {
            "P": np.zeros((0, 3)) if P is None else P,
            "report": np.array(json.dumps(dataclasses.asdict(rep))),
            "how": np.array(how),
        }

    d = cached_arrays(path, build)
    try:
        rep = ContactReport(**json.loads(str(d["report"])))
    except (TypeError, ValueError):
        # written by a development version whose report had other fields: rebuilt
        if path is not None:
            path.unlink(missing_ok=True)
        d = cached_arrays(path, build)
        rep = ContactReport(**json.loads(str(d["report"])))
    how = str(d["how"])
    return (None if how == "none" else d["P"]), rep, how


def _rest_overlap(
    scene: Scene,
    drive: Drive,
    muscles: dict[str, tuple[FloatArray, IntArray]],
    bones: dict[str, tuple[FloatArray, IntArray]],
    cache: Path | None,
    say: Callable[[str], None],
    notes: list[str],
) -> tuple[
    dict[str, tuple[FloatArray, IntArray]],
    dict[str, dict[str, FloatArray | None]],
    dict[str, IntArray],
]:
    """Muscles out of their bones at the rest pose (or their overlap kept), once per run.

    Every mesh is in its body's frame. With ``rest_overlap = "resolve"`` each
    muscle's vertices inside (or within the margin of) a bone at the rest pose
    are pushed out, volume-exact (`musclewrap.solver.push_out`), and the pushed
    mesh is the one prepared; with ``"keep"`` each vertex may stay as deep as it
    was. A muscle with most of its vertices inside one bone is refused: its
    mesh, frame or units do not match the bone's.

    Returns the muscles; per muscle, the bones it is kept out of with each one's
    allowance (``"keep"``); and per muscle its anchors: the vertices within
    ``defaults.anchor_reach`` mean edge lengths of the margin of a bone that its
    own body carries, in patches near an end of its action lines (an origin,
    which moves with that bone: `Muscle.bind`'s anchors keep them in place, so
    the deformation does not drive the muscle into the bone it starts from;
    `musclewrap.solver.attachment_patches`).
    """
    from ..constants import defaults
    from ..mesh import mean_edge_length, vertex_adjacency
    from ..solver import Placed, attachment_patches

    cache_str = None if cache is None else str(cache)
    probes: dict[str, Any] = {}

    def probe(b: str) -> Any:  # built (or read back) only where a muscle's outcome is not kept
        if b not in probes:
            V, F = bones[b]
            probes[b] = _bone_probe(V, F, Obstacle.cache_name(V, F), cache_str)
        return probes[b]

    body_of = {b.name: b.body for b in scene.bones}
    out_muscles = dict(muscles)
    contact: dict[str, dict[str, FloatArray | None]] = {}
    anchors: dict[str, IntArray] = {}
    for spec in scene.muscles:
        V, F = muscles[spec.name]
        names = list(spec.bones) if spec.bones is not None else list(bones)
        T = {b: drive.to_body[b] @ np.linalg.inv(drive.to_body[spec.name]) for b in names}
        lines = drive.rest_lines[spec.name]
        key = digest(
            V,
            F,
            *(Obstacle.cache_name(*bones[b]) for b in names),
            *(T[b] for b in names),
            *(np.asarray(lines[k], dtype=np.float64) for k in sorted(lines)),
            repr((names, sorted(lines), [body_of[b] == spec.body for b in names])),
            repr((spec.name, scene.margin, scene.rest_overlap, scene.mesh_unit)),
            repr((defaults.anchor_reach, defaults.anchor_end_reach, __version__)),
        )

        def build(
            spec: Any = spec,
            V: FloatArray = V,
            F: IntArray = F,
            names: list[str] = names,
            T: dict[str, FloatArray] = T,
            lines: dict[str, FloatArray] = lines,
        ) -> dict[str, np.ndarray]:
            said: list[str] = []
            placed = []
            for b in names:
                pl = Placed(probe(b), T[b], None, b)
                n_in, depth = pl.obstacle.measure(pl.to_obstacle(V))
                if n_in > 0.5 * len(V):
                    raise SceneError(
                        f"{spec.mesh}: {n_in} of the {len(V)} vertices of '{spec.name}' lie "
                        f"inside the bone '{b}' ({depth:.3g} {scene.mesh_unit} deep) at the rest "
                        "pose: the muscle and bone meshes must be the same subject's, in the same "
                        "frame and units (or leave this bone out of the muscle's [muscles] bones)"
                    )
                placed.append(pl)
            keep = scene.rest_overlap == "keep"
            if placed and not keep:
                _, V, keep = _resolve_rest(spec, V, F, placed, scene, cache, _silent, said)
            out: dict[str, np.ndarray] = {"V": V, "notes": np.array(said, dtype=str)}
            for pl in placed:
                a = _kept_allowance(pl, V, scene.margin) if keep else None
                if a is not None:
                    out[f"allowance {pl.name}"] = a
            reach = scene.margin + defaults.anchor_reach * mean_edge_length(V, F)
            found = [
                pl.obstacle.query(pl.to_obstacle(V), reach)[0]
                for pl in placed
                if body_of[pl.name] == spec.body
            ]
            out["anchors"] = attachment_patches(
                vertex_adjacency(F, len(V)),
                V,
                np.concatenate(found) if found else np.zeros(0, np.int64),
                lines,
            )
            return out

        d = cached_arrays(None if cache is None else cache / f"rest-outcome-{key[:32]}.npz", build)
        for n in (str(x) for x in d["notes"]):
            notes.append(n)
            say(n)
        contact[spec.name] = {b: d.get(f"allowance {b}") for b in names}
        out_muscles[spec.name] = (np.asarray(d["V"], dtype=np.float64), F)
        anchors[spec.name] = np.asarray(d["anchors"], dtype=np.int64)
    return out_muscles, contact, anchors


def _silent(_: str) -> None:
    """Says nothing (what is said is kept, and said on every run)."""


def _kept_allowance(pl: Any, V: FloatArray, margin: float) -> FloatArray | None:
    """A kept rest overlap: each vertex nearer the bone than the margin may stay as near."""
    idx, phi, _, _ = pl.obstacle.query(pl.to_obstacle(V), margin)
    if not len(idx):
        return None
    a = np.full(len(V), np.inf)
    a[idx] = phi
    return a


def _resolve_rest(
    spec: Any,
    V: FloatArray,
    F: IntArray,
    placed: list[Any],
    scene: Scene,
    cache: Path | None,
    say: Callable[[str], None],
    notes: list[str],
) -> tuple[Any, FloatArray, bool]:
    """One muscle's rest overlap pushed out (`_push_out_rest`), said in the notes.

    Returns the push-out's report, the positions to prepare, and whether the
    overlap is kept instead (every push folded the surface).
    """
    P, rep, how = _push_out_rest(V, F, placed, scene.margin, cache)
    if rep.rounds == 0:
        return rep, V, False
    if not rep.ok:
        raise SceneError(
            f"{spec.mesh}: the overlap of '{spec.name}' with its bones at the rest pose "
            f"cannot be resolved ({rep.reason}); set [collisions] rest_overlap = 'keep'"
        )
    if P is None:
        msg = (
            f"{spec.name}: rest overlap with bones kept (up to {rep.depth_before:.3g} "
            f"{scene.mesh_unit} deep): pushing it out folds the surface; only new "
            "penetration is prevented"
        )
    else:
        msg = (
            f"{spec.name}: rest overlap with bones resolved: {rep.contact_vertices} vertices "
            f"now at the bones, up to {rep.depth_before:.3g} {scene.mesh_unit} deep before; "
            f"largest displacement {rep.moved_max:.3g} {scene.mesh_unit}; volume kept"
            + ("" if how == "bone vertices" else "; bone vertices inside the muscle left")
        )
    notes.append(msg)
    say(msg)
    return rep, (V if P is None else P), P is None


def _input_files(scene: Scene) -> list[Path]:
    """Every file the scene reads."""
    files = [scene.path, *scene.motions, *(m.mesh for m in scene.muscles)]
    files += [b.mesh for b in scene.bones]
    files += [p for p in (scene.osim, scene.lines_csv) if p is not None]
    if scene.registration is not None:
        files += [lm.mesh for lm in scene.registration.landmarks]
    return files


def _check_outputs_spare_inputs(scene: Scene, outdir: Path) -> None:
    """Refuse an output folder where the run would write over one of its inputs."""
    clash = overwrite_clash(
        _input_files(scene),
        [outdir / n for n in _TOP_FILES],
        [outdir / m.name for m in scene.muscles] + [outdir / b.name for b in scene.bones],
    )
    if clash is not None:
        raise SceneError(
            f"{clash[0]}: an input of the scene lies where the run writes its outputs (in "
            f"{outdir}); musclewrap never writes over its inputs: choose another output "
            "folder (-o)"
        )


def _run_key(scene: Scene, drive: Drive, collisions: bool) -> str:
    """Hash of everything a run's outputs depend on: files, settings, frames, version."""
    files = _input_files(scene)
    return digest(
        *(f.read_bytes() for f in files),
        np.asarray(drive.frames),
        f"{__version__}|collisions={collisions}",
    )


def _run(
    scene: Scene,
    outdir: Path,
    drive: Drive,
    muscles: dict[str, tuple[FloatArray, IntArray]],
    bones: dict[str, tuple[FloatArray, IntArray]],
    cache: Path | None,
    pool: _Pool | None,
    progress: Any,
    notes: list[str],
    key: str,
    resume: bool,
    contact: dict[str, dict[str, FloatArray | None]] | None,
    anchors: dict[str, IntArray] | None = None,
    input_ids: dict[str, IntArray] | None = None,
    frames_written: Callable[[], None] | None = None,
) -> RunSummary:
    from ..output import write_csv, write_pvd

    outdir.mkdir(parents=True, exist_ok=True)
    n = len(drive.frames)
    # per bone: mesh in its body frame, its transforms to the output frame, its probe's name
    bone_local = {
        b.name: (
            *bones[b.name],
            drive.to_output[b.body],
            Obstacle.cache_name(*bones[b.name]),
            b.name,
        )
        for b in scene.bones
    }
    jobs = []
    run = os.urandom(8).hex()  # tells a worker's kept muscle from another run's
    for spec in scene.muscles:
        Vb, F = muscles[spec.name]
        jobs.append(
            {
                "name": spec.name,
                "source": str(spec.mesh),
                "V": Vb,
                "F": F,
                "input_id": (np.arange(len(Vb)) if input_ids is None else input_ids[spec.name]),
                "cage_size": spec.cage_size,
                "cage_coarsening": spec.cage_coarsening,
                "cache_dir": None if cache is None else str(cache),
                "method": spec.method,
                "max_iterations": spec.max_iterations,
                "rest_lines": drive.rest_lines[spec.name],
                "rest_reference": drive.rest_reference[spec.name],
                "lines": drive.lines[spec.name],
                "references": drive.references[spec.name],
                "to_output": drive.to_output[spec.body],
                "frames": drive.frames,
                "times": drive.times,
                "bones": list(bone_local.values()),
                "contact": None if contact is None else contact[spec.name],
                "anchors": None if anchors is None else anchors[spec.name],
                "margin": scene.margin,
                "outdir": str(outdir),
                "paper_frames": scene.paper_frames,
                "run": run,
                **_fibre_job(scene, drive, spec),
            }
        )
        if jobs[-1]["fibres"] is not None:
            ids = jobs[-1]["input_id"]
            for key in ("origin", "insertion"):
                jobs[-1]["fibres"][key] = _attachment_area(scene, drive, spec, key, Vb, ids)
    bar = _Progress(n * len(jobs), progress) if progress is not None else None
    entries: list[tuple[int, str]] = []

    def write_bones() -> None:
        # one file per frame where the bone moves in the output frame, else one file
        for bname, (V, F, T, *_) in bone_local.items():
            DV, DF = _bone_display(V, F, scene.bone_display_faces, cache)
            if np.allclose(T, T[0], atol=1e-9 * (1 + np.abs(T).max())):
                fname = f"{bname}/{bname}.vtp"
                write_mesh(outdir / fname, apply(T[0], DV), DF)
                entries.extend((k, fname) for k in range(n))
                continue
            for k, frame in enumerate(drive.frames):
                fname = f"{bname}/{bname}_{frame:04d}.vtp"
                write_mesh(outdir / fname, apply(T[k], DV), DF)
                entries.append((k, fname))

    # largest muscles first: the pool then finishes about together
    jobs.sort(key=lambda j: -len(j["V"]))
    # what is not cached yet is built first, spread over the workers, then read back by all
    fill: list[tuple[str, Any]] = [
        ("muscle", j) for j in jobs if not (p := _prepare_path(j)) or not p.is_file()
    ]
    if cache is not None:
        fill += [
            ("bone", (V, F, name, str(cache)))
            for V, F, _, name, _ in bone_local.values()
            if not (cache / name).is_file()
        ]
        # fibres of a muscle prepared already (those of one prepared here come with it)
        fill += [
            ("fibres", j)
            for j in jobs
            if ("muscle", j) not in fill and (p := _fibres_path(j)) and not p.is_file()
        ]
    chunks = _chunks(n, len(jobs), 0 if pool is None else pool.n)
    journal = Journal(outdir, key, [(c.start, c.stop) for c in chunks], resume)
    notes += journal.notes
    chunks = [range(a, b) for a, b in journal.chunks]
    results = _execute(jobs, chunks, fill, pool, bar, journal, meanwhile=write_bones)
    order = {s.name: i for i, s in enumerate(scene.muscles)}
    results.sort(key=lambda r: order[r["name"]])
    rows = [r for res in results for r in res["rows"]]
    for res in results:
        entries += res["entries"]
        if res["note"]:
            notes.append(res["note"])
    entries.sort(key=lambda e: e[0])
    files = [
        write_pvd(outdir / PVD, [(float(drive.times[k]), f) for k, f in entries]),
        write_csv(outdir / REPORT, rows, REPORT_FIELDS),
    ]
    if frames_written is not None:
        frames_written()
    if scene.fibres is not None:
        paths = {s.name: s.paths for s in scene.muscles}
        files += write_fibre_outputs(outdir, drive, results, paths, notes)
    files += _plots(outdir, scene, results, contact is not None)
    worst = max(
        (abs(r["relative_volume_error"]) if np.isfinite(r["relative_volume_error"]) else np.inf)
        for r in rows
    )
    summary = RunSummary(
        outdir=outdir,
        n_frames=n,
        muscles=[s.name for s in scene.muscles],
        rows=rows,
        worst_volume_error=float(worst),
        unconverged=sum(not r["converged"] for r in rows),
        seconds=0.0,
        seconds_prepare={r["name"]: r["seconds_prepare"] for r in results},
        cache_hits=[r["name"] for r in results if r["cache_hit"]],
        notes=notes,
        files=files,
    )
    return summary


def _attachment_area(
    scene: Scene, drive: Drive, spec: Any, key: str, V: FloatArray, input_id: IntArray
) -> IntArray | None:
    """A muscle's ``fibre_origin``/``fibre_insertion`` as its vertex numbers (None: default)."""
    given = getattr(spec, f"fibre_{key}")
    if given is None:
        return None
    where = f"{scene.path}: [muscles.{spec.name}] fibre_{key}"
    if isinstance(given[0], int):
        area = np.flatnonzero(np.isin(input_id, np.asarray(given, dtype=np.int64)))
        if not len(area):
            raise SceneError(
                f"{where}: none of its vertex indices is a vertex of {spec.mesh.name} "
                f"(indices 0 to {int(input_id.max())} after merging and repair)"
            )
        return area
    # landmark points, in the mesh's coordinates: the surface within landmark_radius
    P = apply(drive.to_body[spec.name], np.array(given, dtype=np.float64))
    from scipy.spatial import cKDTree

    d, _ = cKDTree(P).query(V)
    radius = scene.fibres.landmark_radius if scene.fibres is not None else 10.0
    area = np.flatnonzero(d <= radius)
    if not len(area):
        raise SceneError(
            f"{where}: no vertex of the muscle lies within landmark_radius = {radius:g} of its "
            f"points (the nearest is {float(d.min()):.3g} away)"
        )
    return area


def _fibre_job(scene: Scene, drive: Drive, spec: Any) -> dict[str, Any]:
    """A muscle job's fibre settings and, for moment arms, its side poses."""
    if scene.fibres is None:
        return {"fibres": None, "ma": None}
    f = scene.fibres
    out: dict[str, Any] = {
        "fibres": {"count": f.count, "points": f.points, "voxels": f.voxels},
        "ma": None,
    }
    ma = drive.moment_arms
    if ma is None:
        return out
    out["ma"] = {
        "coordinates": ma.coordinates,
        "steps": ma.steps,
        "per_q": ma.per_q,
        "contact": f.moment_arm_contact,
    }
    out["ma_lines"] = ma.lines[spec.name]
    out["ma_references"] = ma.references[spec.name]
    out["ma_to_output"] = ma.to_output[spec.body]
    out["ma_bone_T"] = {b.name: ma.to_output[b.body] for b in scene.bones}
    return out


class _Pool:
    """Worker processes (spawned), with a queue that carries progress ticks back."""

    def __init__(self, n: int) -> None:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        ctx = mp.get_context("spawn")
        self.queue = ctx.Queue()
        threads = max(1, (os.cpu_count() or 1) // n)
        self.executor = ProcessPoolExecutor(
            max_workers=n, mp_context=ctx, initializer=_init_worker, initargs=(self.queue, threads)
        )
        # one task per worker starts them all now, each importing what the jobs need
        self.n = n
        for _ in range(n):
            self.executor.submit(_warm_up)

    def __enter__(self) -> _Pool:
        return self

    def __exit__(self, kind: object, *_: object) -> None:
        # On an error, queued work is dropped, but the workers are still waited for: one
        # left starting up after this process unlinked the queue's semaphore would print
        # a traceback of its own.
        self.executor.shutdown(wait=True, cancel_futures=kind is not None)


def _warm_up() -> None:
    import igl  # noqa: F401

    from .. import contact  # noqa: F401
    from ..solver import Muscle  # noqa: F401


def _import_matplotlib() -> None:
    with contextlib.suppress(Exception):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401


def _chunks(n_frames: int, n_jobs: int, workers: int) -> list[range]:
    """Frame ranges per muscle: about three tasks per worker, for an even finish.

    At most 128 frames each: a chunk is also what an interrupted run keeps.
    """
    k = 1 if workers <= 1 else max(1, min(-(-3 * workers // n_jobs), n_frames // 20))
    k = max(k, -(-n_frames // 128))
    edges = np.linspace(0, n_frames, k + 1).round().astype(int)
    return [range(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def _execute(
    jobs: list[dict[str, Any]],
    chunks: list[range],
    fill: list[tuple[str, Any]],
    pool: _Pool | None,
    bar: _Progress | None,
    journal: Journal,
    *,
    meanwhile: Callable[[], None],
) -> list[dict[str, Any]]:
    """Run the jobs in frame chunks, then each muscle's comparison with the paper.

    Chunks and comparisons found in the journal (an interrupted run) are kept;
    each one finished here is recorded there at once. In worker processes,
    whatever `fill` puts into the cache is built first. Returns one result per
    job.
    """
    compare = jobs[0]["paper_frames"] > 0
    kept = {
        (j["name"], ks.start): part
        for j in jobs
        for ks in chunks
        if (part := journal.chunk(j["name"], ks.start, ks.stop)) is not None
    }
    if bar is not None and kept:
        bar.add(sum(len(part["rows"]) for part in kept.values()))

    def chunk_done(j: dict[str, Any], ks: range, part: dict[str, Any]) -> dict[str, Any]:
        journal.save_chunk(j["name"], ks.start, ks.stop, part)
        return part

    def compare_done(j: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
        journal.save_comparison(j["name"], result)
        return result

    if pool is None:
        global _progress_queue
        meanwhile()
        _progress_queue = _LocalQueue(bar)
        try:
            results = []
            for j in jobs:
                res = _merge(
                    j,
                    [
                        kept.get((j["name"], ks.start))
                        or chunk_done(j, ks, _frames_job(_slice(j, ks)))
                        for ks in chunks
                    ],
                )
                if compare:
                    res.update(
                        journal.comparison(j["name"])
                        or compare_done(j, _compare_job(j, _comparison_frames(res["rows"])))
                    )
                results.append(res)
            return results
        finally:
            _progress_queue = None
    import queue as queue_mod
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    def ticks(timeout: float | None) -> None:
        while True:
            try:
                k = pool.queue.get(timeout=timeout) if timeout else pool.queue.get_nowait()
            except queue_mod.Empty:
                return
            if bar is not None:
                bar.add(k)
            if timeout:
                return

    submit = pool.executor.submit
    try:
        filled = [submit(_fill_cache, t) for t in fill]
        meanwhile()
        built = {r["name"]: r for f in filled if (r := f.result())}
        # per job and chunk: a kept result, or the future of one
        parts: list[list[Any]] = [
            [kept.get((j["name"], ks.start)) or submit(_frames_job, _slice(j, ks)) for ks in chunks]
            for j in jobs
        ]
        # this process waits from here on: it imports the plotting library meanwhile
        threading.Thread(target=_import_matplotlib, daemon=True).start()
        results: list[dict[str, Any] | None] = [None] * len(jobs)
        compares: dict[int, Any] = {}
        while not all(c.done() for c in compares.values()) or None in results:
            ticks(0.05)
            for i, row in enumerate(parts):
                for c, x in enumerate(row):
                    if isinstance(x, Future) and x.done():
                        row[c] = chunk_done(jobs[i], chunks[c], x.result())
                if results[i] is None and all(isinstance(x, dict) for x in row):
                    results[i] = _merge(jobs[i], row)
                    if not compare:
                        continue
                    found = journal.comparison(jobs[i]["name"])
                    if found is not None:
                        results[i].update(found)  # type: ignore[union-attr]
                    else:  # queued behind the remaining chunks
                        compares[i] = submit(
                            _compare_job, jobs[i], _comparison_frames(results[i]["rows"])
                        )
        for i, f in compares.items():
            results[i].update(compare_done(jobs[i], f.result()))  # type: ignore[union-attr]
    except BrokenProcessPool:
        raise RuntimeError(
            "a worker process died without a Python error (out of memory, a crash in a compiled "
            "library, or, from a Python script, run_scene called outside an `if __name__ == "
            "'__main__':` block); rerun with --workers 1 to see where"
        ) from None
    ticks(None)
    out = [r for r in results if r is not None]
    for r in out:  # the preparation happened in phase one
        r.update(built.get(r["name"], {}))
    return out


class _LocalQueue:
    def __init__(self, bar: _Progress | None) -> None:
        self.bar = bar

    def put(self, n: int) -> None:
        if self.bar is not None:
            self.bar.add(n)


def _check_units(
    scene: Scene, drive: Drive, muscles: dict[str, tuple[FloatArray, IntArray]]
) -> None:
    """Refuse a muscle whose rest lines cannot belong to its mesh (both in its body frame)."""
    from ..conditions import placement_problem

    for spec in scene.muscles:
        problem = placement_problem(muscles[spec.name][0], drive.rest_lines[spec.name])
        if problem is not None:
            raise SceneError(
                f"{spec.mesh}: the rest action lines of '{spec.name}' ({scene.mesh_unit}): "
                f"{problem}: check [units] (mesh = '{scene.mesh_unit}', model = "
                f"'{scene.model_unit}'), the muscle's body ('{spec.body}'), or the rest pose"
            )


def _plots(
    outdir: Path, scene: Scene, results: list[dict[str, Any]], collisions: bool
) -> list[Path]:
    from ..output import plot_convergence, plot_penetration, plot_volume_error

    series = {}
    for res in results:
        rows = res["rows"]
        series[f"{res['name']} (sqp)"] = (
            [r["frame"] for r in rows],
            [r["relative_volume_error"] for r in rows],
        )
    paper = {res["name"]: res["paper"] for res in results if res["paper"]}
    files = [
        plot_volume_error(
            outdir / PLOT_VOLUME,
            series,
            title=f"{scene.name}: relative volume error per frame",
            markers={
                f"{m} (paper, eq. 11)": ([p[0] for p in ps], [p[1] for p in ps])
                for m, ps in paper.items()
            },
        )
    ]
    conv = {
        res["name"]: (res["worst_frame"], res["convergence"])
        for res in results
        if res["convergence"]
    }
    if conv:
        files.append(
            plot_convergence(
                outdir / PLOT_CONVERGENCE,
                conv,
                title=f"{scene.name}: convergence on the worst frame",
            )
        )
    if scene.bones:

        def depth(key: str) -> dict[str, tuple[list[int], list[float]]]:
            return {
                res["name"]: ([r["frame"] for r in res["rows"]], [r[key] for r in res["rows"]])
                for res in results
            }

        files.append(
            plot_penetration(
                outdir / PLOT_PENETRATION,
                depth("penetration_depth_max"),
                before=depth("penetration_depth_before") if collisions else None,
                title=f"{scene.name}: muscles in bones"
                + ("" if collisions else " (collisions off)"),
                unit=scene.mesh_unit,
            )
        )
    return files

"""Writing a run's outputs: the ParaView series, the report, the plots, the summary.

Frame files are written by the tasks (`._work`), each whole or not at all; what is
written here comes from the results the tasks send back, in the client.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._cache import cached_arrays
from .._hashing import cache_key
from .._typing import FloatArray, IntArray
from ..mesh import apply_transform, write_mesh
from ..output import plot_convergence, plot_penetration, plot_volume_error, write_csv, write_pvd
from ..scene import OUTPUT_COLUMNS, Drive, Scene
from ._fibres import write_fibre_outputs
from ._files import (
    PLOT_CONVERGENCE,
    PLOT_PENETRATION,
    PLOT_VOLUME,
    PVD,
    REPORT,
)
from ._records import BoneMesh, MuscleOutcome

__all__ = ["REPORT_FIELDS", "Progress", "RunSummary", "write_bones", "write_outputs"]

#: columns of ``report.csv`` (the first eight are the documented contract; their meanings:
#: `OUTPUT_COLUMNS`, which the documentation lists)
REPORT_FIELDS = list(OUTPUT_COLUMNS["report.csv"])


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
    #: the pictures' camera (`musclewrap.output.View`), whether or not they were drawn
    view: Any = None

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
            + f"; skeleton fit mean <= {worst('skeleton_fit_mean'):.3g}"
            + (
                " (where the lines lie outside the bones <= "
                + f"{np.nanmax([r.get('skeleton_fit_free', np.nan) for r in solved] + [0.0]):.3g})"
                if any(r.get("lines_conflict_max", 0) > 0 for r in solved)
                else ""
            )
            + "; "
            f"shape change <= {worst('shape_change_max'):.3g} edge lengths; deepest bone "
            f"penetration {worst('penetration_depth_max'):.3g}"
            + (
                f" (without contact {worst('penetration_depth_before'):.3g}; up to "
                f"{max((r['contact_vertices'] for r in solved), default=0)} contact vertices)"
                if any(r["contact_vertices"] for r in solved)
                else ""
            )
            + (
                f"; deepest vertex in another muscle {worst('muscle_overlap_max'):.3g}"
                + _rounds_text(solved)
                if any(np.isfinite(r.get("muscle_overlap_max", np.nan)) for r in solved)
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


def _rounds_text(rows: list[dict[str, Any]]) -> str:
    """The muscles' rounds a frame (`musclewrap.solver.meet`): median, most, and where."""
    by_frame = {r["frame"]: r.get("muscle_rounds", 0) for r in rows}
    if not by_frame:
        return ""
    most = max(by_frame, key=lambda k: by_frame[k])
    return (
        f" after {np.median(list(by_frame.values())):g} rounds a frame (median; most "
        f"{by_frame[most]}, frame {most})"
    )


def _bone_display(
    V: FloatArray, F: IntArray, faces: int, cache: Path | None
) -> tuple[FloatArray, IntArray]:
    """A lighter copy of a bone for display (VTK quadric decimation; copes with defects).

    Decimating a 90K-face bone takes about a second, the same every run: the result is
    kept in the preparation cache.
    """
    if faces == 0 or len(F) <= faces:
        return V, F
    path = None if cache is None else cache / f"bone-{cache_key(V, F, str(faces))[:32]}.npz"

    def build() -> dict[str, np.ndarray]:
        DV, DF = _decimate(V, F, faces)
        return {"V": DV, "F": DF}

    d = cached_arrays(path, build)
    return d["V"], d["F"]


def _plots(
    outdir: Path, scene: Scene, results: list[MuscleOutcome], collisions: bool
) -> list[Path]:

    series = {}
    for res in results:
        rows = res.rows
        series[res.name] = (
            [r["frame"] for r in rows],
            [r["relative_volume_error"] for r in rows],
        )
    paper = {res.name: res.comparison.paper for res in results if res.comparison.paper}
    files = [
        plot_volume_error(
            outdir / PLOT_VOLUME,
            series,
            title=f"{scene.name}: relative volume error per frame",
            markers={m: ([p[0] for p in ps], [p[1] for p in ps]) for m, ps in paper.items()},
            # each muscle's own method (the old figure said "sqp" whatever it was)
            line_label=", ".join(sorted({m.method for m in scene.muscles})),
            marker_label="paper, eq. 11",
        )
    ]
    conv = {
        res.name: (res.comparison.worst_frame, res.comparison.convergence)
        for res in results
        if res.comparison.convergence
    }
    if conv:
        files.append(
            plot_convergence(
                outdir / PLOT_CONVERGENCE,
                conv,
                title=f"{scene.name}: convergence on the worst frame",
            )
        )

    def depth(key: str) -> dict[str, tuple[list[int], list[float]]]:
        return {
            res.name: ([r["frame"] for r in res.rows], [r.get(key, float("nan")) for r in res.rows])
            for res in results
        }

    together = any(
        np.isfinite(r.get("muscle_overlap_max", np.nan)) for res in results for r in res.rows
    )
    if scene.bones or together:
        files.append(
            plot_penetration(
                outdir / PLOT_PENETRATION,
                depth("penetration_depth_max"),
                before=depth("penetration_depth_before") if collisions else None,
                bone_inside=depth("bone_inside_depth_max") if collisions else None,
                line_inside=depth("line_inside_depth_max"),
                title=f"{scene.name}: muscles and bones in each other"
                + ("" if collisions or together else " (collisions off)"),
                unit=scene.mesh_unit,
                muscle_inside=depth("muscle_overlap_max") if together else None,
            )
        )
    return files


class Progress:
    """One progress display over a run or a batch: muscle-frames done of all, rate, time left.

    On a terminal a bar redrawn in place; otherwise a line per tenth. ``total``
    grows as a batch's scenes are planned (`grow`), and so do the GIFs' pictures
    (`grow_pictures`), counted beside the frames.
    """

    def __init__(self, total: int, stream: Any) -> None:
        self.total, self.done, self.stream = total, 0, stream
        self.pictures, self.pictures_done = 0, 0
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self._last = -1
        self._skipped = 0  # kept from an interrupted run: not part of the rate
        self._ended = False

    def grow(self, n: int) -> None:
        self.total += n
        self._ended = False

    def grow_pictures(self, n: int) -> None:
        self.pictures += n
        self._ended = False

    def skip(self, n: int) -> None:
        """``n`` muscle-frames kept from an interrupted run (done, not timed)."""
        self._skipped += n
        self.add(n)

    def add(self, n: int) -> None:
        self.done += n
        self._show()

    def add_pictures(self, n: int) -> None:
        self.pictures_done += n
        self._show()
        if not self.tty and self.pictures_done >= self.pictures:
            self.stream.write(f"{self.pictures_done}/{self.pictures} pictures drawn\n")
            self.stream.flush()

    def _show(self) -> None:
        pct = int(100 * self.done / max(self.total, 1))
        elapsed = time.perf_counter() - self.t0
        rate = (self.done - self._skipped) / elapsed if elapsed > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else float("nan")
        tail = f"{rate:.1f}/s, {left:.0f} s left" if np.isfinite(left) else "starting"
        if self.tty:
            bar = "#" * (pct // 4)
            pictures = f", pictures {self.pictures_done}/{self.pictures}" if self.pictures else ""
            self.stream.write(
                f"\r[{bar:<25}] {self.done}/{self.total} muscle-frames {elapsed:5.1f} s "
                f"({tail}){pictures}   "
            )
            if self.done >= self.total and self.pictures_done >= self.pictures and not self._ended:
                self.stream.write("\n")
                self._ended = True
        elif pct // 10 != self._last // 10:
            self.stream.write(f"{pct:3d}% ({self.done}/{self.total} muscle-frames; {tail})\n")
        self._last = pct
        self.stream.flush()


def _decimate(V: FloatArray, F: IntArray, faces: int) -> tuple[FloatArray, IntArray]:
    import pyvista as pv

    cells = np.hstack([np.full((len(F), 1), 3), F]).ravel()
    d = pv.PolyData(V, cells).decimate(1.0 - faces / len(F))
    if not d.n_cells:
        return V, F
    G = d.faces.reshape(-1, 4)[:, 1:]
    return np.asarray(d.points, dtype=np.float64), np.ascontiguousarray(G, dtype=np.int64)


def write_bones(
    outdir: Path,
    bones: Sequence[BoneMesh],
    to_output: dict[str, FloatArray],
    frames: Sequence[int],
    faces: int,
    cache: Path | None,
) -> list[tuple[int, str]]:
    """Each bone's display mesh, written; returns the series entries (frame index, file).

    One file per frame where the bone moves in the output frame, else one file.
    """
    entries: list[tuple[int, str]] = []
    n = len(frames)
    for b in bones:
        T = to_output[b.name]
        DV, DF = _bone_display(b.V, b.F, faces, cache)
        if np.allclose(T, T[0], atol=1e-9 * (1 + np.abs(T).max())):
            fname = f"{b.name}/{b.name}.vtp"
            write_mesh(outdir / fname, apply_transform(T[0], DV), DF)
            entries.extend((k, fname) for k in range(n))
            continue
        for k, frame in enumerate(frames):
            fname = f"{b.name}/{b.name}_{frame:04d}.vtp"
            write_mesh(outdir / fname, apply_transform(T[k], DV), DF)
            entries.append((k, fname))
    return entries


def write_outputs(
    outdir: Path,
    scene: Scene,
    drive: Drive,
    results: list[MuscleOutcome],
    entries: list[tuple[int, str]],
    collisions: bool,
    notes: list[str],
) -> tuple[list[dict[str, Any]], list[Path]]:
    """The series, the report, the fibres' tables and the plots; returns the rows and files."""
    rows = [r for res in results for r in res.rows]
    entries = sorted(entries + [e for res in results for e in res.entries], key=lambda e: e[0])
    for res in results:
        if res.note:
            notes.append(res.note)
    files = [
        write_pvd(outdir / PVD, [(float(drive.times[k]), f) for k, f in entries]),
        write_csv(outdir / REPORT, rows, REPORT_FIELDS),
    ]
    if scene.fibres is not None and scene.fibres.output:
        paths = {s.name: s.paths for s in scene.muscles}
        files += write_fibre_outputs(outdir, drive, results, paths, notes, scene.mesh_unit)
    files += _plots(outdir, scene, results, collisions)
    return rows, files

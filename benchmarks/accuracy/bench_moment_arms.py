"""Fibres' and action lines' moment arms on the LHDL hip sweeps: accuracy, step and cost.

    python benchmarks/accuracy/bench_moment_arms.py [SCENE] [--steps 0.5,1,2,4] [--repeats 3]
    python benchmarks/accuracy/bench_moment_arms.py SCENE --smoothness [--fibres-of SCENE2]
        [--attachments ends|bones] [--attached] [--count N] [--line-window W]
    python benchmarks/accuracy/bench_moment_arms.py SCENE --scan MUSCLE [--about START:STOP:STEP]
        [--span DEG] [--by DEG] [--line-reach X|none] [--fibres-of SCENE2]

1. The action line's moment arm against OpenSim's ``computeMomentArm`` on every frame of
   every motion, the frames where the path's points change between the frame and a side
   pose included (there the difference is one-sided): the largest difference per path
   (target 0.5 mm).
2. Per step (degrees), with the side poses deformed without and with the bones' contact
   (``[fibres] moment_arm_contact``): the scene run with its ``[fibres]``;
   per muscle and the coordinate its motion sweeps: the fibres' moment arm range and
   mean over the sweep, the action line's, and the roughness of the fibres' mean over
   the frames (median and largest |second difference|, mm: what the step leaves of
   the contact's discrete steps; a smooth curve has ~0.1 or less), and the fibre-frames
   more than 3 mm from the median of their 5 neighbouring frames (issue 25), every frame.
3. Cost: the warm run with ``[fibres]`` against ``--no-fibres``, alternately,
   ``--repeats`` times each (CLI, all workers), medians and ratio (target <= 1.3x);
   ``--steps ""`` runs only this.
4. ``--smoothness`` (only this): the scene run once (its ``[fibres]``, or those of
   ``--fibres-of``: the LHDL walk and squat have none); per muscle and coordinate, every
   frame: the fibre-frames more than 3 mm from the median of their 5 neighbouring frames,
   the largest such distance, the largest on the motion's interior frames, the first
   and last frames' largest distance from a quadratic through the 5 end frames (where
   the median's window is one-sided), and the action line's largest difference from
   OpenSim; per muscle, about the swept coordinate, the range across fibres of each
   fibre's 90th percentile of the moment arm and of its negative (the published
   figures' peak flexion and extension moment arms); and the range by the published
   figures' own procedure (`_quartic_ranges`: the fibres' lengths on the sweep's frames,
   a quartic in time, not the side poses), each against the published range.
5. ``--scan MUSCLE`` (only this): the muscle alone through hip flexion -5 to 5 deg in
   0.1-deg steps without contact; each fibre's ``dL/dq`` between neighbouring poses,
   and the poses where it steps (by more than 0.5 mm against a median step of a few
   hundredths): the psoas's "stairs".
6. ``--scan MUSCLE --about START:STOP:STEP`` (only this): the muscle alone, without
   contact, in process, at the poses of the scene's motion rows START:STOP:STEP, each
   with hip flexion moved by -SPAN to SPAN degrees in steps of BY (default 0: the rows
   themselves), ``defaults.line_reach`` set to ``--line-reach`` ("none": every sample
   bound): per pose, the mean fibre length, the iterations and the volume of the
   unconstrained solution (``x_ls``, conditions without the volume) over the rest
   volume. Jumps of the mean length between neighbouring poses are the solve landing in
   different minima of the volume-constrained problem (the gait2392 semitendinosus).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from musclewrap.fibres import LHDL_FIBRE_RANGES, published_cover

ROOT = Path(__file__).resolve().parents[2]


def line_against_opensim(scene) -> None:  # noqa: ANN001
    from musclewrap.scene import drive_scene

    print("action line against OpenSim's computeMomentArm, mm (every frame):")
    worst: dict[str, float] = {}
    for motion in scene.motions:
        sc = dataclasses.replace(scene, motions=(motion,))
        d = drive_scene(sc, None, {b.name: np.zeros(3) for b in sc.bones})
        ma = d.moment_arms
        for p in ma.line:
            diff = np.abs(ma.line[p] - ma.opensim[p])
            worst[p] = max(worst.get(p, 0.0), float(diff.max()))
            n = int(ma.switch[p].sum())
            if n:
                print(
                    f"  {motion.stem}: {p}: {n} frame x coordinate(s) one-sided (a switch), "
                    f"there |difference| <= {float(diff[ma.switch[p]].max()):.4f}"
                )
    for p, w in worst.items():
        print(f"  {p:14s} largest |difference| {w:.4f}")


def sweep_table(scene, step: float, workers: int, contact: bool) -> None:  # noqa: ANN001
    from musclewrap.scene import run_scene

    fibres = dataclasses.replace(scene.fibres, step=step, moment_arm_contact=contact)
    sc = dataclasses.replace(scene, fibres=fibres)
    print(f"step {step:g} deg, side poses {'with' if contact else 'without'} bone contact:")
    print(
        "  motion          muscle            fibres min..max  mean   line   roughness median / max"
        "   > 3 mm off"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for j, motion in enumerate(sc.motions):
            one = dataclasses.replace(sc, motions=(motion,))
            run_scene(one, Path(tmp) / motion.stem, workers=workers, progress=None, render=False)
            rows = list(csv.DictReader(open(Path(tmp) / motion.stem / "moment_arms.csv")))
            jc = min(j, len(sc.fibres.moment_arms) - 1)
            coord = sc.fibres.moment_arms[jc]
            spikes = _spikes(Path(tmp) / motion.stem / "fibres.csv", coord)
            for m in sc.muscles:
                r = [x for x in rows if x["muscle"] == m.name and x["coordinate"] == coord]
                lo, mean, hi, line = (
                    np.array([float(x[k]) for x in r])
                    for k in ("fibre_min", "fibre_mean", "fibre_max", "line_moment_arm")
                )
                d2 = np.abs(np.diff(mean, 2))
                print(
                    f"  {motion.stem:15s} {m.name:16s} {np.nanmin(lo):6.1f}..{np.nanmax(hi):5.1f} "
                    f"{np.nanmean(mean):6.1f} {np.nanmean(line):6.1f}   "
                    f"{np.nanmedian(d2):6.2f} / {np.nanmax(d2):6.1f}"
                    f"   {spikes.get(m.name, (0, 0))[0]} of {spikes.get(m.name, (0, 0))[1]}"
                )


def smoothness(scene, workers: int) -> None:  # noqa: ANN001
    """Issue 25's targets on every motion of ``scene``, every coordinate of its fibres."""
    import time

    from musclewrap.scene import OpenSimModel, run_scene

    covers: list[float] = []
    quartic: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        for motion in scene.motions:
            one = dataclasses.replace(scene, motions=(motion,), gif=False)
            t = time.perf_counter()
            run_scene(one, Path(tmp) / motion.stem, workers=workers, progress=None, render=False)
            wall = time.perf_counter() - t
            folder = Path(tmp) / motion.stem
            arms = list(csv.DictReader(open(folder / "moment_arms.csv")))
            print(f"{motion.stem}: {wall:.1f} s (cold run)")
            print(
                "  coordinate        muscle            off / fibre-frames  largest  interior"
                "  ends-quadratic  line-OpenSim"
            )
            for c in scene.fibres.moment_arms:
                spikes = _spikes(folder / "fibres.csv", c, largest=True)
                for m in scene.muscles:
                    big, total, worst, inner, ends = spikes[m.name]
                    line = max(
                        abs(float(x["line_moment_arm"]) - float(x["opensim_moment_arm"]))
                        for x in arms
                        if x["muscle"] == m.name and x["coordinate"] == c
                    )
                    print(
                        f"  {c:17s} {m.name:16s} {big:7d} / {total:<9d} {worst:7.1f} mm "
                        f"{inner:6.2f} mm {ends:8.2f} mm {line:10.4f} mm"
                    )
            swept = _swept(folder / "fibres.csv", scene.fibres.moment_arms)
            if swept is not None:
                print(
                    f"  about {swept}, smallest .. largest across fibres and frames (mm), mean, "
                    "against the published fibres (LHDL_FIBRE_RANGES):"
                )
                for m, (lo, hi, mean) in _ranges(folder / "fibres.csv", swept).items():
                    row = f"    {m:16s} {lo:6.1f} .. {hi:6.1f}  mean {mean:6.1f}"
                    pub = LHDL_FIBRE_RANGES.get((swept, m))
                    if pub is not None:
                        covers.append(published_cover(lo, hi, pub))
                        row += (
                            f"   published {pub[0]:6.1f} .. {pub[1]:6.1f}: width "
                            f"{(hi - lo) / (pub[1] - pub[0]):.2f}, covers {covers[-1]:.0%} of it"
                            + ("" if min(hi, pub[1]) > max(lo, pub[0]) else " (no overlap)")
                        )
                    print(row)
                print(
                    f"  about {swept}, across fibres on one frame (the median over the frames of "
                    "the largest less the smallest) and the action line's range (mm):"
                )
                for m, spread in _frame_spread(folder / "fibres.csv", swept).items():
                    line = [
                        float(x["line_moment_arm"])
                        for x in arms
                        if x["muscle"] == m and x["coordinate"] == swept
                    ]
                    print(f"    {m:16s} {spread:6.2f}   line {min(line):6.1f} .. {max(line):6.1f}")
                # the same figures by the published ranges' own procedure, so that like is
                # compared with like: their fibres' lengths on the sweep's frames (solved as
                # the frames are, with all their contact), not side poses
                print(
                    f"  about {swept} by the published figures' procedure (each fibre's length "
                    "over the frames and the angle each a quartic in time, differenced on 5x "
                    "the frames), mm:"
                )
                angle = OpenSimModel(scene.osim).is_rotational(swept)
                for m, (lo, hi) in _quartic_ranges(folder / "fibres.csv", swept, angle).items():
                    row = f"    {m:16s} {lo:6.1f} .. {hi:6.1f}"
                    pub = LHDL_FIBRE_RANGES.get((swept, m))
                    if pub is not None:
                        quartic.append(published_cover(lo, hi, pub))
                        row += (
                            f"   published {pub[0]:6.1f} .. {pub[1]:6.1f}: "
                            f"covers {quartic[-1]:.0%} of it"
                        )
                    print(row)
                print(f"  per fibre the 90th percentile about {swept}, range across fibres (mm):")
                for m, (pos, neg) in _peaks(folder / "fibres.csv", swept).items():
                    print(
                        f"    {m:16s} r: {pos[0]:6.1f} .. {pos[1]:6.1f}   -r: {neg[0]:6.1f} .. {neg[1]:6.1f}"
                    )
    if covers:
        print(f"the published ranges covered: {np.mean(covers):.1%} on average ({len(covers)})")
    if quartic:
        print(
            f"  by the published figures' procedure: {np.mean(quartic):.1%} on average "
            f"({len(quartic)})"
        )


def _series(path: Path, coord: str) -> dict[tuple[str, str], NDArray[np.float64]]:
    """Each (muscle, fibre)'s moment arm about ``coord`` over the frames, in order."""
    got: dict[tuple[str, str], list[tuple[int, float]]] = {}
    for x in csv.DictReader(open(path)):
        if x["coordinate"] == coord:
            got.setdefault((x["muscle"], x["fibre"]), []).append(
                (int(x["frame"]), float(x["moment_arm"]))
            )
    return {key: np.array([v for _, v in sorted(g)]) for key, g in got.items()}


def _spikes(path: Path, coord: str, largest: bool = False) -> dict[str, Any]:
    """Per muscle: fibre-frames off their neighbours, and all fibre-frames.

    Off: the moment arm about ``coord`` more than 3 mm from the median of its 5
    neighbouring frames (fewer at the ends). With ``largest`` also the largest such
    distance, the largest on interior frames and the largest distance of a first or
    last frame from a quadratic through the 5 end frames.
    """
    out: dict[str, Any] = {}
    for (m, _), r in _series(path, coord).items():
        off = np.abs(r - [np.median(r[max(0, i - 2) : i + 3]) for i in range(len(r))])
        ends = 0.0
        if len(r) >= 5:
            x = np.arange(len(r))
            for end, sl in ((0, slice(0, 5)), (len(r) - 1, slice(-5, None))):
                fit = np.polyval(np.polyfit(x[sl], r[sl], 2), end)
                ends = max(ends, abs(float(r[end] - fit)))
        inner = float(off[1:-1].max()) if len(r) > 2 else 0.0
        big, total, worst, inn, end_ = out.get(m, (0, 0, 0.0, 0.0, 0.0))
        out[m] = (
            big + int((off > 3.0).sum()),
            total + len(r),
            max(worst, float(off.max())),
            max(inn, inner),
            max(end_, ends),
        )
    return out if largest else {m: v[:2] for m, v in out.items()}


def _swept(path: Path, coords: Any) -> str | None:
    """The moment-arm coordinate whose value changes over the frames (one only), or None."""
    values: dict[str, set[str]] = {}
    for x in csv.DictReader(open(path)):
        values.setdefault(x["coordinate"], set()).add(x["coordinate_value"])
    moving = [c for c in coords if len(values.get(c, ())) > 1]
    return moving[0] if len(moving) == 1 else None


def _ranges(path: Path, coord: str) -> dict[str, tuple[float, float, float]]:
    """Per muscle, the smallest and largest moment arm about ``coord`` and the mean."""
    per: dict[str, list[NDArray[np.float64]]] = {}
    for (m, _), r in _series(path, coord).items():
        per.setdefault(m, []).append(r)
    out = {}
    for m, rs in per.items():
        a = np.concatenate(rs)
        out[m] = (float(a.min()), float(a.max()), float(a.mean()))
    return out


def _frame_spread(path: Path, coord: str) -> dict[str, float]:
    """Per muscle, the median over the frames of its fibres' largest less smallest moment arm."""
    per: dict[str, list[NDArray[np.float64]]] = {}
    for (m, _), r in _series(path, coord).items():
        per.setdefault(m, []).append(r)
    return {m: float(np.median(np.ptp(np.array(rs), axis=0))) for m, rs in per.items()}


def _quartic_ranges(path: Path, coord: str, angle: bool = True) -> dict[str, tuple[float, float]]:
    """Per muscle, the fibres' moment arms about ``coord`` as the published ranges were made.

    Modenese & Kohout's repository (modenaxe/3d-muscles, the script that computes the
    fibres' moment arms): each fibre's length over the sweep's frames and the swept angle
    (radians) are each fitted by a polynomial of degree 4 in time, both evaluated on 5
    times as many evenly spaced times, and the moment arm is the ratio of their
    differences; the range is the smallest and largest across fibres and those times.
    Here ``-dL/dq`` (OpenSim's sign, as the published table); ``angle``: the coordinate
    is rotational (its values in degrees, the moment arm per radian), else a translation.
    """
    got: dict[tuple[str, str], dict[int, tuple[float, float, float]]] = {}
    for x in csv.DictReader(open(path)):
        if x["coordinate"] == coord and x["coordinate_value"] != "":
            got.setdefault((x["muscle"], x["fibre"]), {})[int(x["frame"])] = (
                float(x["time"]), float(x["coordinate_value"]), float(x["length"])
            )  # fmt: skip
    out: dict[str, tuple[float, float]] = {}
    for (m, _), rows in got.items():
        t, q, length = np.array([rows[f] for f in sorted(rows)]).T
        if len(t) < 5:
            continue
        fine = np.linspace(t[0], t[-1], 5 * len(t))
        dq = np.diff(np.polyval(np.polyfit(t, np.radians(q) if angle else q, 4), fine))
        r = -np.diff(np.polyval(np.polyfit(t, length, 4), fine)) / dq
        lo, hi = out.get(m, (np.inf, -np.inf))
        out[m] = (min(lo, float(r.min())), max(hi, float(r.max())))
    return out


def _peaks(path: Path, coord: str) -> dict[str, tuple[tuple[float, float], ...]]:
    """Per muscle, the range across fibres of the 90th percentile of r and of -r."""
    per: dict[str, list[tuple[float, float]]] = {}
    for (m, _), r in _series(path, coord).items():
        per.setdefault(m, []).append((np.percentile(r, 90), np.percentile(-r, 90)))
    return {
        m: tuple((float(min(v)), float(max(v))) for v in zip(*got, strict=True))
        for m, got in per.items()
    }


def scan(scene, muscle: str, workers: int) -> None:  # noqa: ANN001
    """Item 5: ``dL/dq`` of each fibre between hip flexion poses 0.1 deg apart."""
    from musclewrap.scene import run_scene, write_motion

    q = np.round(np.linspace(-5.0, 5.0, 101), 6)
    with tempfile.TemporaryDirectory() as tmp:
        cols = {"hip_flexion_r": q, "hip_adduction_r": 0 * q, "hip_rotation_r": 0 * q}
        mot = write_motion(Path(tmp) / "scan.mot", 0.01 * np.arange(len(q)), cols)
        one = dataclasses.replace(
            scene,
            motions=(mot,),
            muscles=tuple(m for m in scene.muscles if m.name == muscle),
            gif=False,
        )
        run_scene(one, Path(tmp) / "o", workers=workers, progress=None, render=False,
                  collisions=False)  # fmt: skip
        L: dict[str, dict[int, float]] = {}
        for x in csv.DictReader(open(Path(tmp) / "o" / "fibres.csv")):
            L.setdefault(x["fibre"], {})[int(x["frame"])] = float(x["length"])
    lengths = np.array([[f[k] for k in sorted(f)] for f in L.values()])
    slope = -np.diff(lengths, axis=1) / np.radians(0.1)  # mm per rad: a moment arm
    change = np.abs(np.diff(slope, axis=1))
    mid = q[1:-1]
    steps = np.flatnonzero(change.max(axis=0) > 0.5)
    print(f"{muscle}: hip flexion -5..5 deg by 0.1, no contact, {len(lengths)} fibres")
    print(f"  median change of dL/dq between neighbouring intervals: {np.median(change):.3f} mm")
    for i in steps:
        print(
            f"  step at {mid[i]:+.1f} deg: dL/dq {slope[:, i].mean():.2f} -> "
            f"{slope[:, i + 1].mean():.2f} mm (mean over fibres; largest fibre's change "
            f"{change[:, i].max():.2f} mm)"
        )


def pose_scan(scene, muscle: str, about: str, span: float, by: float, reach: str | None) -> None:  # noqa: ANN001
    """Item 6: mean fibre length, iterations and the unconstrained volume, pose by pose."""
    import musclewrap.solver._deformer as solver
    from musclewrap.constants import defaults
    from musclewrap.mesh import volume
    from musclewrap.scene import read_motion, run_scene, write_motion

    motion = read_motion(scene.motion)
    rows = range(motion.n_frames)[slice(*(int(x) if x else None for x in about.split(":")))]
    dq = np.round(np.arange(-span, span + by / 2, by), 6) if span > 0 else np.zeros(1)
    held = scene.coordinates or tuple(motion.columns)
    cols = {c: np.repeat(motion.columns[c][list(rows)], len(dq)) for c in held}
    cols["hip_flexion_r"] = cols["hip_flexion_r"] + np.tile(dq, len(rows))
    one = dataclasses.replace(
        scene,
        muscles=tuple(m for m in scene.muscles if m.name == muscle),
        fibres=dataclasses.replace(scene.fibres, moment_arms=()),
        collisions=False,
        gif=False,
        paper_frames=0,
    )
    volumes: list[float] = []
    iterations: list[int] = []
    deform = solver.Deformer.deform

    def measured(self, lines, **kw):  # noqa: ANN001, ANN003, ANN202
        # the solution of the conditions alone (no volume), as the solve starts from it
        _, s_cur, d_L = self._targets(lines, kw.get("reference_point"))
        x_ls = self._HL @ d_L + self._HS @ s_cur + self._x_anchor
        volumes.append(volume(self.muscle.W @ x_ls, self.muscle.F) / self.muscle.volume_rest)
        r = deform(self, lines, **kw)
        iterations.append(r.iterations)
        return r

    old = defaults.line_reach
    if reach is not None:
        object.__setattr__(defaults, "line_reach", None if reach == "none" else float(reach))
    solver.Deformer.deform = measured
    try:
        with tempfile.TemporaryDirectory() as tmp:
            t = 0.01 * np.arange(len(dq) * len(rows))
            # undeclared units: the values are as the run read them (degrees where it guessed so)
            deg = motion.in_degrees or not motion.degrees_declared
            mot = write_motion(Path(tmp) / "scan.mot", t, cols, in_degrees=deg)
            run_scene(dataclasses.replace(one, motions=(mot,)), Path(tmp) / "o", workers=1,
                      progress=None, render=False)  # fmt: skip
            L: dict[int, list[float]] = {}
            for x in csv.DictReader(open(Path(tmp) / "o" / "fibres.csv")):
                L.setdefault(int(x["frame"]), []).append(float(x["length"]))
    finally:
        solver.Deformer.deform = deform
        object.__setattr__(defaults, "line_reach", old)
    if len(volumes) != len(L):
        raise SystemExit(f"{len(volumes)} solves for {len(L)} poses: cannot pair them")
    moved = f"{-span:+g} to {span:+g} deg by {by:g}" if span > 0 else "0 deg"
    print(f"{muscle}: {scene.motion.name} rows {about}, hip flexion moved by {moved}, "
          f"no contact, line_reach {defaults.line_reach if reach is None else reach}")  # fmt: skip
    print("  row   dq (deg)  mean fibre length (mm)  iterations  unconstrained volume / rest")
    for k in sorted(L):
        print(f"  {rows[k // len(dq)]:4d} {dq[k % len(dq)]:+8.1f} {np.mean(L[k]):18.1f} "
              f"{iterations[k]:11d} {volumes[k]:18.3f}")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_hip_sweeps.toml"))
    p.add_argument("--steps", default="0.5,1,2,4")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--tables-only", action="store_true", help="skip the timing")
    p.add_argument("--smoothness", action="store_true", help="only item 4")
    p.add_argument("--fibres-of", help="a scene whose [fibres] table to use")
    p.add_argument("--attachments", choices=("ends", "bones"), help="[fibres] attachments")
    p.add_argument("--attached", action="store_true", help="[fibres] attached = true")
    p.add_argument("--count", type=int, help="[fibres] count")
    p.add_argument("--line-window", type=float, help="the scene's line_window")
    p.add_argument("--scan", metavar="MUSCLE", help="only item 5 (or 6), for this muscle")
    p.add_argument("--about", metavar="START:STOP:STEP", help="item 6: the motion's rows")
    p.add_argument("--span", type=float, default=0.0, help="item 6: degrees of flexion either side")
    p.add_argument("--by", type=float, default=0.2, help="item 6: degrees between poses")
    p.add_argument("--line-reach", help="item 6: mean thicknesses, or none (default: the default)")
    a = p.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the shared helpers
    from _common import timed_run
    from musclewrap.scene import load_scene

    scene = load_scene(Path(a.scene))
    if a.fibres_of:
        scene = dataclasses.replace(scene, fibres=load_scene(Path(a.fibres_of)).fibres)
    if scene.fibres is None or not scene.fibres.moment_arms:
        raise SystemExit(f"{a.scene}: no [fibres] moment_arms")
    if a.attachments:
        scene = dataclasses.replace(
            scene, fibres=dataclasses.replace(scene.fibres, attachments=a.attachments)
        )
    if a.attached:
        scene = dataclasses.replace(scene, fibres=dataclasses.replace(scene.fibres, attached=True))
    if a.count:
        scene = dataclasses.replace(scene, fibres=dataclasses.replace(scene.fibres, count=a.count))
    if a.line_window is not None:
        scene = dataclasses.replace(scene, line_window=a.line_window)
    if a.smoothness:
        smoothness(scene, a.workers)
        return
    if a.scan and a.about:
        pose_scan(scene, a.scan, a.about, a.span, a.by, a.line_reach)
        return
    if a.scan:
        scan(scene, a.scan, a.workers)
        return
    line_against_opensim(scene)
    for contact in (False, True):
        for step in (float(s) for s in a.steps.split(",") if s):
            sweep_table(scene, step, a.workers, contact)
    if a.tables_only:
        return
    with tempfile.TemporaryDirectory() as tmp:
        on, off = Path(tmp) / "on", Path(tmp) / "off"
        timed_run(a.scene, on, [])  # warm: preparations and fibres cached
        t_on, t_off = [], []
        for _ in range(a.repeats):
            t_off.append(timed_run(a.scene, off, ["--no-fibres"]))
            t_on.append(timed_run(a.scene, on, []))
    m_on, m_off = statistics.median(t_on), statistics.median(t_off)
    print(f"{a.scene}: warm, {a.repeats} runs each, alternating")
    print(
        f"  with [fibres]: median {m_on:.1f} s; --no-fibres: {m_off:.1f} s; "
        f"{m_on / m_off:.2f}x  (all: {', '.join(f'{t:.1f}' for t in t_on)} / "
        f"{', '.join(f'{t:.1f}' for t in t_off)})"
    )


if __name__ == "__main__":
    main()

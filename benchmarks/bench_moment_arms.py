"""Fibres' and action lines' moment arms on the LHDL hip sweeps: accuracy, step and cost.

    python benchmarks/bench_moment_arms.py [SCENE] [--steps 0.5,1,2,4] [--repeats 3]
    python benchmarks/bench_moment_arms.py SCENE --smoothness [--fibres-of SCENE2]

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
   the largest such distance, and the action line's largest difference from OpenSim.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import statistics
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


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

    from musclewrap.scene import run_scene

    with tempfile.TemporaryDirectory() as tmp:
        for motion in scene.motions:
            one = dataclasses.replace(scene, motions=(motion,), gif=False)
            t = time.perf_counter()
            run_scene(one, Path(tmp) / motion.stem, workers=workers, progress=None, render=False)
            wall = time.perf_counter() - t
            folder = Path(tmp) / motion.stem
            arms = list(csv.DictReader(open(folder / "moment_arms.csv")))
            print(f"{motion.stem}: {wall:.1f} s (cold run)")
            print("  coordinate        muscle            off / fibre-frames  largest  line-OpenSim")
            for c in scene.fibres.moment_arms:
                spikes = _spikes(folder / "fibres.csv", c, largest=True)
                for m in scene.muscles:
                    big, total, worst = spikes[m.name]
                    line = max(
                        abs(float(x["line_moment_arm"]) - float(x["opensim_moment_arm"]))
                        for x in arms
                        if x["muscle"] == m.name and x["coordinate"] == c
                    )
                    print(
                        f"  {c:17s} {m.name:16s} {big:7d} / {total:<9d} {worst:7.1f} mm "
                        f"{line:8.4f} mm"
                    )


def _spikes(path: Path, coord: str, largest: bool = False) -> dict[str, Any]:
    """Per muscle: fibre-frames off their neighbours, and all fibre-frames.

    Off: the moment arm about ``coord`` more than 3 mm from the median of its 5
    neighbouring frames (fewer at the ends).
    """
    series: dict[tuple[str, str], list[tuple[int, float]]] = {}
    for x in csv.DictReader(open(path)):
        if x["coordinate"] == coord:
            series.setdefault((x["muscle"], x["fibre"]), []).append(
                (int(x["frame"]), float(x["moment_arm"]))
            )
    out: dict[str, Any] = {}
    for (m, _), got in series.items():
        r = np.array([v for _, v in sorted(got)])
        off = np.abs(r - [np.median(r[max(0, i - 2) : i + 3]) for i in range(len(r))])
        big, total, worst = out.get(m, (0, 0, 0.0))
        out[m] = (big + int((off > 3.0).sum()), total + len(r), max(worst, float(off.max())))
    return out if largest else {m: v[:2] for m, v in out.items()}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_hip_sweeps.toml"))
    p.add_argument("--steps", default="0.5,1,2,4")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--tables-only", action="store_true", help="skip the timing")
    p.add_argument("--smoothness", action="store_true", help="only item 4")
    p.add_argument("--fibres-of", help="a scene whose [fibres] table to use")
    a = p.parse_args()
    from musclewrap._bench import timed_run
    from musclewrap.scene import load_scene

    scene = load_scene(Path(a.scene))
    if a.fibres_of:
        scene = dataclasses.replace(scene, fibres=load_scene(Path(a.fibres_of)).fibres)
    if scene.fibres is None or not scene.fibres.moment_arms:
        raise SystemExit(f"{a.scene}: no [fibres] moment_arms")
    if a.smoothness:
        smoothness(scene, a.workers)
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

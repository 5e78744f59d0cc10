"""Fibres' and action lines' moment arms on the LHDL hip sweeps: accuracy, step and cost.

    python benchmarks/bench_moment_arms.py [SCENE] [--steps 0.5,1,2,4] [--repeats 3]

1. The action line's moment arm by central differences against OpenSim's
   ``computeMomentArm`` on every frame of every motion, away from the frames where the
   central difference straddles a change of the path's points (a conditional via point
   or wrap switching): the largest difference per path (target 0.1 mm).
2. Per step (degrees), with the side poses deformed without and with the bones' contact
   (``[fibres] moment_arm_contact``): the scene run with its ``[fibres]``;
   per muscle and the coordinate its motion sweeps: the fibres' moment arm range and
   mean over the sweep, the action line's, and the roughness of the fibres' mean over
   the frames (median and largest |second difference|, mm: what the step leaves of
   the contact's discrete steps; a smooth curve has ~0.1 or less).
3. Cost: the warm run with ``[fibres]`` against ``--no-fibres``, alternately,
   ``--repeats`` times each (CLI, all workers), medians and ratio (target <= 1.3x);
   ``--steps ""`` runs only this.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import statistics
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def line_against_opensim(scene) -> None:  # noqa: ANN001
    from musclewrap.scene import drive_scene

    print("action line (central differences) against OpenSim's computeMomentArm, mm:")
    worst: dict[str, float] = {}
    for motion in scene.motions:
        sc = dataclasses.replace(scene, motions=(motion,))
        d = drive_scene(sc, None, {b.name: np.zeros(3) for b in sc.bones})
        ma = d.moment_arms
        for p in ma.line:
            diff = np.abs(ma.line[p] - ma.opensim[p])[~ma.switch[p]]
            worst[p] = max(worst.get(p, 0.0), float(diff.max()))
            n = int(ma.switch[p].sum())
            if n:
                print(
                    f"  {motion.stem}: {p}: {n} frame x coordinate(s) straddle a switch (left out)"
                )
    for p, w in worst.items():
        print(f"  {p:14s} largest |difference| {w:.4f}")


def sweep_table(scene, step: float, workers: int, contact: bool) -> None:  # noqa: ANN001
    from musclewrap.scene import drive_scene, run_scene

    fibres = dataclasses.replace(scene.fibres, step=step, moment_arm_contact=contact)
    sc = dataclasses.replace(scene, fibres=fibres)
    print(f"step {step:g} deg, side poses {'with' if contact else 'without'} bone contact:")
    print(
        "  motion          muscle            fibres min..max  mean   line   roughness median / max"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for j, motion in enumerate(sc.motions):
            one = dataclasses.replace(sc, motions=(motion,))
            run_scene(one, Path(tmp) / motion.stem, workers=workers, progress=None, render=False)
            rows = list(csv.DictReader(open(Path(tmp) / motion.stem / "moment_arms.csv")))
            jc = min(j, len(sc.fibres.moment_arms) - 1)
            coord = sc.fibres.moment_arms[jc]
            ma = drive_scene(one, None, {b.name: np.zeros(3) for b in sc.bones}).moment_arms
            for m in sc.muscles:
                # frames where one of its paths switches points are left out (noted by the run)
                switch = np.any([ma.switch[p][:, jc] for p in m.paths], axis=0)
                r = [x for x in rows if x["muscle"] == m.name and x["coordinate"] == coord]
                r = [x for x, sw in zip(r, switch, strict=True) if not sw]
                lo, mean, hi, line = (
                    np.array([float(x[k]) for x in r])
                    for k in ("fibre_min", "fibre_mean", "fibre_max", "line_moment_arm")
                )
                d2 = np.abs(np.diff(mean, 2))
                print(
                    f"  {motion.stem:15s} {m.name:16s} {np.nanmin(lo):6.1f}..{np.nanmax(hi):5.1f} "
                    f"{np.nanmean(mean):6.1f} {np.nanmean(line):6.1f}   "
                    f"{np.nanmedian(d2):6.2f} / {np.nanmax(d2):6.1f}"
                )


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_hip_sweeps.toml"))
    p.add_argument("--steps", default="0.5,1,2,4")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--tables-only", action="store_true", help="skip the timing")
    a = p.parse_args()
    from musclewrap._bench import timed_run
    from musclewrap.scene import load_scene

    scene = load_scene(Path(a.scene))
    if scene.fibres is None or not scene.fibres.moment_arms:
        raise SystemExit(f"{a.scene}: no [fibres] moment_arms")
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

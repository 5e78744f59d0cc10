"""Muscles stepped together against a step each: the rounds, what they leave, what they cost.

    python benchmarks/accuracy/bench_joint.py [SCENE] [--frames 0:211:50] [--modes each,joint]
        [--motion MOT [--negate COORDINATE ...]] [--conditions C]

Runs the scene warm in one process (``--workers 1``, one BLAS and Numba thread, no GIF),
once per mode in turns in one sitting: ``each`` (``[collisions] together = false``, a step
of its cage per muscle with its share of every overlap, the default) and ``joint``
(``true``: the muscles that overlap in a round step together,
`musclewrap.solver._group.joint_round`); ``jointN``: joint with ``N`` conditions a leading
cage vertex (``defaults.muscle_joint_points``, set in this process); ``--conditions``: a
group's conditions past which they are pooled one a cage vertex
(``defaults.muscle_joint_conditions``, set likewise). ``--motion``: the
scene driven by another motion, ``--negate`` its coordinates negated first. Prints per
mode the wall time and, from its report.csv, the rounds a frame (median, most, sum), and
the largest muscle-in-muscle depth, shape change, bone vertex in a muscle, volume error
and ``skeleton_fit_free``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

#: report.csv columns printed (largest over the run)
COLUMNS = (
    "muscle_overlap_max",
    "shape_change_max",
    "bone_inside_depth_max",
    "relative_volume_error",
    "skeleton_fit_free",
)


def _column(rows: list[dict[str, str]], key: str) -> np.ndarray:
    return np.array([float(r[key]) for r in rows if r.get(key) not in (None, "", "nan")])


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "gait2392_hip_thigh.toml"))
    p.add_argument("--frames", default="0:211:50")
    p.add_argument("--modes", default="each,joint")
    p.add_argument("--motion", default=None)
    p.add_argument("--negate", nargs="*", default=[])
    p.add_argument("--conditions", type=int, default=None)
    a = p.parse_args()
    import numba
    from threadpoolctl import threadpool_limits

    import musclewrap.solver._group as group
    from musclewrap.constants import defaults
    from musclewrap.scene import load_scene, read_motion, run_scene, write_motion

    threadpool_limits(1)
    numba.set_num_threads(1)
    scene = dataclasses.replace(load_scene(a.scene), paper_frames=0)
    with tempfile.TemporaryDirectory() as tmp:
        if a.motion is not None:
            mot = read_motion(a.motion)
            cols = {k: (-v if k in a.negate else v) for k, v in mot.columns.items()}
            path = Path(tmp) / Path(a.motion).name
            write_motion(path, mot.time, cols, in_degrees=mot.in_degrees)
            scene = dataclasses.replace(scene, motions=(path,))
        kw = dict(frames=a.frames, workers=1, render=False, progress=None,
                  cache_dir=Path(tmp) / "cache")  # fmt: skip
        run_scene(scene, Path(tmp) / "warm", **kw)
        print(f"{scene.name}: frames {a.frames}, one process, warm")
        for mode in a.modes.split(","):
            out = Path(tmp) / mode
            t0 = time.perf_counter()
            points = int(mode[5:]) if mode[5:] else defaults.muscle_joint_points
            cap = defaults.muscle_joint_conditions if a.conditions is None else a.conditions
            group.defaults = dataclasses.replace(
                defaults, muscle_joint_points=points, muscle_joint_conditions=cap
            )
            run_scene(dataclasses.replace(scene, muscle_together=mode != "each"), out, **kw)
            wall = time.perf_counter() - t0
            with open(out / "report.csv", newline="") as fh:
                rows = list(csv.DictReader(fh))
            rounds = _column(rows, "muscle_rounds")
            ok = sum(r["converged"] in ("True", "true", "1") for r in rows)
            figures = ", ".join(f"{k} {_column(rows, k).max():.3g}" for k in COLUMNS)
            print(
                f"  {mode:<5} {wall:6.1f} s, {ok} of {len(rows)} converged, rounds a frame "
                f"median {np.median(rounds):.0f}, most {rounds.max():.0f}, "
                f"sum {rounds.sum():.0f}; {figures}"
            )


if __name__ == "__main__":
    main()

"""``musclewrap init`` + ``musclewrap check`` on a folder of meshes: time, warm (issue 26).

    python benchmarks/tuning/bench_init.py [--repeats 3] [--folder ../shared/data/vhf]
    python benchmarks/tuning/bench_init.py --paths examples/gait2392_hip_thigh.toml examples/lhdl_walk.toml

Runs init (the gait2392 subject01 model, the walk) and check (with its picture) on the
folder ``--repeats`` times in this process after one warm-up (the meshes' cache and the
imports warm), and prints the medians. The 30 s target is for both together.

``--paths SCENE...``: the threshold of check's "lines far from their muscle"
(`defaults.check_far_thicknesses`) on either side: per muscle of each scene, its
own paths' nearest quarter outside it, and the nearest of every other muscle's paths, in
mean thicknesses (4 V / A).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--folder", default=str(DATA / "vhf"))
    p.add_argument("--paths", nargs="+", help="scenes whose muscles to hold every path against")
    a = p.parse_args()
    if a.paths:
        _paths(a.paths)
        return
    from musclewrap.scene import check_scene
    from musclewrap.subject import init_scene

    osim = DATA / "opensim/models/subject01_simbody.osim"
    motion = DATA / "opensim/motions/subject01_walk1_ik.mot"
    ti, tc = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(a.repeats + 1):
            t0 = time.perf_counter()
            r = init_scene(osim, Path(a.folder), Path(tmp) / "s.toml", motion=motion)
            t1 = time.perf_counter()
            rep = check_scene(r.scene, picture=Path(tmp) / "check.png")
            t2 = time.perf_counter()
            if k:  # the first is the warm-up
                ti.append(t1 - t0)
                tc.append(t2 - t1)
    print(
        f"{len(r.muscles)} muscles, {len(r.bones)} bones, {len(r.unplaced)} not placed; check: "
        f"{len(rep.errors)} errors"
    )
    print(
        f"init {statistics.median(ti):.2f} s, check with picture {statistics.median(tc):.2f} s, "
        f"together {statistics.median([x + y for x, y in zip(ti, tc, strict=True)]):.2f} s "
        f"(medians of {a.repeats})"
    )


def _paths(scenes: list[str]) -> None:
    import numpy as np

    from musclewrap.mesh import apply_transform, mean_thickness
    from musclewrap.model import line_fits
    from musclewrap.run._read import _read_muscle, default_cache_dir
    from musclewrap.scene import OpenSimModel, drive_scene, load_scene, rest_pose
    from musclewrap.subject import path_anatomy

    print(f"{'scene':20s} {'muscle':22s} own  nearest other path")
    for f in scenes:
        sc = load_scene(f)
        model = OpenSimModel(sc.osim)
        drive = drive_scene(sc, "0:1", {})
        model.set_pose(rest_pose(sc, model))
        for m in sc.muscles:
            V, F, _, _ = _read_muscle(m, default_cache_dir())
            V = apply_transform(drive.to_body[m.name], V)
            t = mean_thickness(V, F)
            own = line_fits(V, F, [dict(drive.rest_lines[m.name])])[0].near / t
            mine = {path_anatomy(p)[0].name for p in m.paths}
            others = [
                p for p in model.path_names
                if path_anatomy(p) is None or path_anatomy(p)[0].name not in mine
            ]  # fmt: skip
            fits = line_fits(V, F, [{p: model.path_points(p, m.body) * sc.scale} for p in others])
            r = np.array([x.near for x in fits]) / t
            k = int(np.argmin(r))
            print(f"{sc.path.stem:20s} {m.name:22s} {own:.2f} {others[k]:12s} {r[k]:.2f}")


if __name__ == "__main__":
    main()

"""Closest points on another muscle's faces: the compiled search against libigl's tree.

    python benchmarks/speed/bench_closest.py [--repeats 7]
    python benchmarks/speed/bench_closest.py --scene SCENE [--frames 0:211:10] [--bins 200 5000]
    python benchmarks/speed/bench_closest.py --facing SCENE

`musclewrap.contact._muscles._closest` takes, per point, the triangles whose bounding spheres
come within the best distance so far, looked for in rings of a uniform grid of their centroids
(no tree to build), for up to `defaults.closest_grid_points` points, and libigl's AABB tree
(`igl.point_mesh_squared_distance`, built per call: the surface moves every round) from
there on. Prints, for capsules of about 2,000, 8,000 and 40,000 triangles (a muscle's facing
faces, an LHDL muscle, the VHF vastus lateralis) and 10 to 10,000 points within the capsule's
wall, the median time of each and the largest difference of their distances
(`defaults.closest_grid_points` says what the threshold rests on).

``--facing SCENE``: the faces of every ordered pair of the scene's muscles that face each
other at rest (`musclewrap.contact.facing_pairs`, what a run finds once per process),
timed twice in one process, then each pair's faces against their definition taken by
brute force (every centroid's distance by libigl, its winding number): how many pairs differ.

``--scene``: the calls a run makes instead (one process, warm: the overlap search's and the
facing faces' own inputs, recorded), each timed again by the grid search and by libigl's tree,
summed by how many points a call has (up to each of ``--bins``): what a threshold gives up
or gains there.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np


def _median(f, repeats: int) -> float:  # noqa: ANN001
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def scene_calls(scene_path: str, frames: str, edges: list[int]) -> None:
    """The grid search against libigl's tree on the calls a run of the scene makes."""
    import igl
    import numba
    from threadpoolctl import threadpool_limits

    import musclewrap.contact._muscles as muscles
    from musclewrap.scene import load_scene, run_scene

    threadpool_limits(1)
    numba.set_num_threads(1)
    scene = dataclasses.replace(load_scene(scene_path), paper_frames=0, gif=False)
    calls = []
    closest = muscles._closest

    def recorded(P, V, F, **kw):  # noqa: ANN001, ANN003, ANN202
        calls.append((np.ascontiguousarray(P), np.ascontiguousarray(V), np.ascontiguousarray(F)))
        return closest(P, V, F, **kw)

    with tempfile.TemporaryDirectory() as tmp:
        kw = dict(frames=frames, workers=1, render=False, progress=None,
                  cache_dir=Path(tmp) / "cache")  # fmt: skip
        run_scene(scene, Path(tmp) / "warm", **kw)
        muscles._closest = recorded
        try:
            run_scene(scene, Path(tmp) / "timed", **kw)
        finally:
            muscles._closest = closest
    bounds = [0, *edges, 10**12]
    groups = {
        (f"<= {hi}" if lo == 0 else f"> {lo}" if hi == 10**12 else f"{lo + 1}-{hi}"): (lo + 1, hi)
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)
    }
    print(f"{scene_path} frames {frames}: {len(calls)} calls of _closest (one process)")
    print("points     calls  grid s  libigl s")
    for label, (lo, hi) in groups.items():
        sel = [c for c in calls if lo <= len(c[0]) <= hi]
        grid = tree = 0.0
        for P, V, F in sel:
            out = np.empty(len(P)), np.empty((len(P), 3)), np.empty(len(P), dtype=np.int64)
            t0 = time.perf_counter()
            muscles._closest_kernel(P, V, F, *out)
            grid += time.perf_counter() - t0
            t0 = time.perf_counter()
            igl.point_mesh_squared_distance(P, V, F)
            tree += time.perf_counter() - t0
        print(f"{label:<9} {len(sel):6d} {grid:7.3f} {tree:9.3f}")


def facing(scene_path: str) -> None:
    """`facing_pairs` of every ordered pair of the scene's muscles at rest: time and exactness."""
    import igl
    import numba
    from threadpoolctl import threadpool_limits

    from musclewrap.constants import defaults
    from musclewrap.contact import facing_pairs
    from musclewrap.mesh import face_normals, winding_numbers
    from musclewrap.scene import load_scene, run_scene
    from musclewrap.solver import _together

    threadpool_limits(1)
    numba.set_num_threads(1)
    scene = dataclasses.replace(load_scene(scene_path), paper_frames=0, gif=False)
    rest: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    kept = _together.facing_pairs

    def recorded(meshes, reach=None, cache=None):  # noqa: ANN001, ANN202
        rest.update(meshes)  # the muscles at rest in one frame, as the run has them
        return kept(meshes, reach, cache)

    _together.facing_pairs = recorded
    try:
        with tempfile.TemporaryDirectory() as tmp:
            run_scene(scene, Path(tmp) / "out", frames="0:1:1", workers=1, render=False,
                      progress=None, cache_dir=Path(tmp) / "cache")  # fmt: skip
    finally:
        _together.facing_pairs = kept
    reach = defaults.muscle_facing_reach
    for _ in range(2):
        t0 = time.perf_counter()
        found = facing_pairs(rest, reach)
        got = {pair: found[pair] for pair in found}
        print(
            f"{scene_path}: facing_pairs, {len(got)} ordered pairs, {time.perf_counter() - t0:.2f} s"
        )
    differ = 0
    for (a, b), faces in got.items():
        cen = rest[b][0][rest[b][1]].mean(axis=1)
        sq, _, C = igl.point_mesh_squared_distance(cen, *rest[a])
        front = ((C - cen) * face_normals(*rest[b])).sum(axis=1) >= 0.0
        near = (np.sqrt(sq) <= reach) & front
        want = np.flatnonzero(near | (winding_numbers(cen, *rest[a]) > 0))
        differ += not np.array_equal(faces, want)
    print(
        f"pairs whose faces differ from brute force (libigl's distances, winding numbers): {differ}"
    )


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--scene")
    p.add_argument("--facing", metavar="SCENE")
    p.add_argument("--frames", default="0:211:10")
    p.add_argument(
        "--bins", type=int, nargs="+", default=[200, 5000],
        help="--scene: the calls summed by points up to each of these counts, and beyond",
    )  # fmt: skip
    a = p.parse_args()
    if a.facing:
        facing(a.facing)
        return
    if a.scene:
        scene_calls(a.scene, a.frames, a.bins)
        return
    import igl

    from musclewrap.contact._muscles import _closest_kernel
    from musclewrap.synthetic import capsule

    rng = np.random.default_rng(0)
    print("triangles points  spheres ms  libigl ms  ratio  largest difference")
    for n_around, segments in ((32, 24), (64, 56), (128, 150)):
        V, F = capsule(radius=20.0, length=160.0, n_around=n_around, cap_rings=8, segments=segments)
        F = np.ascontiguousarray(F, dtype=np.int64)
        for k in (10, 30, 100, 200, 300, 1000, 3000, 10000):
            # points inside the wall, within 3 of the surface (vertices of a neighbour inside)
            u = rng.normal(size=(k, 2))
            u /= np.linalg.norm(u, axis=1)[:, None]
            P = np.column_stack(
                [(20.0 - rng.uniform(0, 3, k))[:, None] * u, rng.uniform(0, 160, k)]
            )
            P = np.ascontiguousarray(P)
            dist, C, face = np.empty(k), np.empty((k, 3)), np.empty(k, dtype=np.int64)
            _closest_kernel(P[:1], V, F, dist[:1], C[:1], face[:1])  # compiled
            mine = _median(lambda: _closest_kernel(P, V, F, dist, C, face), a.repeats)  # noqa: B023
            tree = _median(lambda: igl.point_mesh_squared_distance(P, V, F), a.repeats)  # noqa: B023
            sq = igl.point_mesh_squared_distance(P, V, F)[0]
            diff = float(np.abs(dist - np.sqrt(sq)).max())
            print(
                f"{len(F):9d} {k:6d} {1e3 * mine:11.2f} {1e3 * tree:10.2f} {tree / mine:6.2f}"
                f"  {diff:.1e}"
            )


if __name__ == "__main__":
    main()

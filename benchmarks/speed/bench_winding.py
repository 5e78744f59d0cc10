"""The fibres' inside check: exact ray-count winding numbers against libigl's hierarchy.

    python benchmarks/speed/bench_winding.py [--points 1500] [--repeats 20]

Per LHDL muscle, 1,500 points uniform in its box (a frame's 100 fibres x 15 points):
`musclewrap.mesh.winding_numbers` against libigl's ``FastWindingNumberBVH`` built and
queried (what the check cost per muscle-frame before), medians of the repeats, and
whether their inside decisions agree.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "lhdl" / "muscles"


def main() -> None:
    import igl

    from musclewrap.mesh import read_mesh, winding_numbers

    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--points", type=int, default=1500)
    ap.add_argument("--repeats", type=int, default=20)
    a = ap.parse_args()
    for path in sorted(DATA.glob("*.vtk")):
        V, F = read_mesh(path)
        P = np.random.default_rng(0).uniform(V.min(axis=0), V.max(axis=0), (a.points, 3))
        winding_numbers(P, V, F)  # compiled
        ray, tree = [], []
        for _ in range(a.repeats):
            t = time.perf_counter()
            w = winding_numbers(P, V, F)
            ray.append(time.perf_counter() - t)
            t = time.perf_counter()
            bvh = igl.FastWindingNumberBVH()
            bvh.init(V, F)
            g = bvh.winding_number(P)
            tree.append(time.perf_counter() - t)
        same = int(np.sum((w >= 1) == (g > 0.5)))
        print(
            f"{path.name:28s} {len(V):5d} vertices: ray count {statistics.median(ray) * 1e3:5.2f} ms, "
            f"libigl hierarchy {statistics.median(tree) * 1e3:5.2f} ms; same decision "
            f"{same}/{len(P)}"
        )


if __name__ == "__main__":
    main()

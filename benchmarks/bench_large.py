"""A muscle of about a million faces: preparation and one pose, time and peak memory.

    python benchmarks/bench_large.py [--faces 1000000]

Peak memory is the process's maximum resident set size (``getrusage``), so it includes the
Python interpreter and the libraries (about 0.3 GiB before any mesh).
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np


def peak_gib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # kB on Linux


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--faces", type=int, default=1_000_000)
    a = ap.parse_args()
    from musclewrap import Muscle
    from musclewrap.synthetic import capsule, capsule_scenario

    # faces = 2 * n_around * (segments + 2 * cap_rings - 1) for the capsule generator
    n_around = int(np.sqrt(a.faces / 2 / 0.6))
    segments = int(0.5 * n_around)
    cap_rings = max(4, n_around // 8)
    V, F = capsule(n_around=n_around, cap_rings=cap_rings, segments=segments)
    print(f"capsule: {len(V):,} vertices, {len(F):,} faces; peak {peak_gib():.2f} GiB")
    t = time.perf_counter()
    m = Muscle.from_mesh(V, F)
    print(f"preparation: {time.perf_counter() - t:.1f} s; peak {peak_gib():.2f} GiB")
    rest, cur = capsule_scenario("bend")
    t = time.perf_counter()
    d = m.bind(rest)
    print(f"bind: {time.perf_counter() - t:.2f} s")
    times = []
    for _ in range(3):
        t = time.perf_counter()
        r = d.deform(cur)
        times.append(time.perf_counter() - t)
    print(
        f"pose: median {sorted(times)[1] * 1e3:.0f} ms over 3; iterations {r.iterations}, "
        f"converged {r.converged}, |volume error| {abs(r.relative_volume_error):.1e}; "
        f"peak {peak_gib():.2f} GiB"
    )


if __name__ == "__main__":
    main()

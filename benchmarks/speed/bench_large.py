"""A muscle of about a million faces: preparation and one pose, time and peak memory.

    python benchmarks/speed/bench_large.py [--faces 1000000] [--scene FRAMES]

Peak memory is the process's maximum resident set size (``getrusage``), so it includes the
Python interpreter and the libraries (about 0.3 GiB before any mesh).

With ``--scene``, the same muscle goes through ``musclewrap run`` instead (a line-CSV scene,
written to a temporary folder: mesh file read, checked and cached, prepared, FRAMES poses of
the capsule scenarios deformed and written as .vtp); the peak is then the largest of this
process and of its worker processes.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np


def peak_gib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # kB on Linux


def capsule_of(faces: int):  # noqa: ANN201
    from musclewrap.synthetic import capsule

    # faces = 2 * n_around * (segments + 2 * cap_rings - 1) for the capsule generator
    n_around = int(np.sqrt(faces / 2 / 0.6))
    segments = int(0.5 * n_around)
    cap_rings = max(4, n_around // 8)
    return capsule(n_around=n_around, cap_rings=cap_rings, segments=segments)


def scene(faces: int, frames: int) -> None:
    import csv
    import tempfile
    from pathlib import Path

    from musclewrap.mesh import write_mesh
    from musclewrap.scene import load_scene, run_scene
    from musclewrap.synthetic import capsule_scenario

    V, F = capsule_of(faces)
    names = ["bend", "bend_short", "bend_long", "short", "rot"]
    with tempfile.TemporaryDirectory(prefix="musclewrap-large-") as tmp:
        d = Path(tmp)
        write_mesh(d / "muscle.vtp", V, F)
        print(
            f"capsule: {len(V):,} vertices, {len(F):,} faces, {(d / 'muscle.vtp').stat().st_size / 2**20:.0f} MiB as .vtp"
        )
        with open(d / "lines.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["frame", "time", "muscle", "line", "point", "x", "y", "z"])
            for k in range(frames):
                rest, cur = capsule_scenario(names[(k - 1) % len(names)])
                lines = rest if k == 0 else cur
                for line, pts in lines.items():
                    for i, p in enumerate(pts):
                        w.writerow([k, 0.1 * k, "capsule", line, i, *p])
        (d / "scene.toml").write_text(
            'name = "large"\n[lines]\ncsv = "lines.csv"\nrest_frame = 0\n'
            '[muscles.capsule]\nmesh = "muscle.vtp"\n[output]\npaper_frames = 0\ngif = false\n'
        )
        t = time.perf_counter()
        s = run_scene(load_scene(d / "scene.toml"), d / "out", cache_dir=d / "cache", progress=None)
        seconds = time.perf_counter() - t
        worst = max(abs(r["relative_volume_error"]) for r in s.rows)
        out = sum(f.stat().st_size for f in (d / "out").rglob("*.vtp")) / 2**20
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20
    print(
        f"scene run, {frames} frames: {seconds:.1f} s (preparation {s.seconds_prepare['capsule']:.1f} s), "
        f"unconverged {s.unconverged}, worst |volume error| {worst:.1e}, {out:.0f} MiB of .vtp; "
        f"peak {max(peak_gib(), children):.2f} GiB (this process {peak_gib():.2f}, children {children:.2f})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--faces", type=int, default=1_000_000)
    ap.add_argument("--scene", type=int, default=0, metavar="FRAMES", help="run a scene instead")
    a = ap.parse_args()
    from musclewrap import Muscle
    from musclewrap.synthetic import capsule_scenario

    if a.scene:
        return scene(a.faces, a.scene)

    V, F = capsule_of(a.faces)
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

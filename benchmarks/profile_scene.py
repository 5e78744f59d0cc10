"""Where a scene's time goes: cProfile of a warm run in one process, on one thread.

    python benchmarks/profile_scene.py [SCENE] [--frames 0:211:1] [--muscle NAME]
        [--no-muscles] [--top 40]

Runs the scene once to warm the caches (preparations, bone probes, compiled kernels), then
again under cProfile with ``--workers 1`` and one BLAS and numba thread (as every task runs),
no GIF and no paper comparison, and prints the cumulative table. ``--no-muscles``: muscles
against bones only (`[collisions] muscles = false`); ``--muscle``: that muscle alone.
cProfile slows the Python parts more than the compiled ones: read it for where, not how long.
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import pstats
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--frames", default="0:211:1")
    p.add_argument("--muscle")
    p.add_argument("--no-muscles", action="store_true")
    p.add_argument("--top", type=int, default=40)
    a = p.parse_args()
    import numba
    from threadpoolctl import threadpool_limits

    from musclewrap.scene import load_scene, run_scene

    threadpool_limits(1)
    numba.set_num_threads(1)
    scene = dataclasses.replace(load_scene(a.scene), paper_frames=0)
    if a.muscle:
        scene = dataclasses.replace(
            scene, muscles=tuple(m for m in scene.muscles if m.name == a.muscle)
        )
    if a.no_muscles:
        scene = dataclasses.replace(scene, muscle_collisions=False)
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "cache"
        kw = dict(frames=a.frames, workers=1, render=False, progress=None, cache_dir=cache)
        run_scene(scene, Path(tmp) / "warm", **kw)
        prof = cProfile.Profile()
        prof.enable()
        run_scene(scene, Path(tmp) / "timed", **kw)
        prof.disable()
    pstats.Stats(prof).sort_stats("cumulative").print_stats(a.top)


if __name__ == "__main__":
    main()

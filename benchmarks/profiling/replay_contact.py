"""One contact function timed on the inputs a run gave it: its calls kept, then replayed.

    python benchmarks/profiling/replay_contact.py [SCENE] [--frames 0:211:16]
        [--function bone_vertices_inside|push_out] [--repeats 3]

Runs the scene's frames once in one process (one thread), keeping a deep copy of every
call's arguments to the function (the bones' `Obstacle` shared, not copied), then calls
the function again on each kept call, ``--repeats`` times, and prints its CPU seconds a
call (the least and the median over the repeats). The inputs are the same in every
repeat and in another checkout's run (``PYTHONPATH=CHECKOUT/src``): what differs is the
code and the host's speed, which on the development VM drifts by 10-30 % over minutes,
so compare checkouts in turns (BENCHMARKS.md, "What contact costs").
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def _shared(args: Any) -> dict[int, Any]:
    """A deepcopy memo that keeps every `Obstacle` reached from ``args`` as it is."""
    from musclewrap.contact import Obstacle

    memo: dict[int, Any] = {}

    def walk(o: Any) -> None:
        if isinstance(o, Obstacle):
            memo[id(o)] = o
        elif isinstance(o, list | tuple):
            for x in o:
                walk(x)
        elif isinstance(o, dict):
            for x in o.values():
                walk(x)
        elif dataclasses.is_dataclass(o) and not isinstance(o, type):
            for f in dataclasses.fields(o):
                walk(getattr(o, f.name))
        elif hasattr(o, "placed"):  # a SideReference
            walk(o.placed)

    walk(args)
    return memo


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--frames", default="0:211:16")
    p.add_argument("--function", default="bone_vertices_inside",
                   choices=("bone_vertices_inside", "push_out"))  # fmt: skip
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    import numba
    from threadpoolctl import threadpool_limits

    from musclewrap.contact import _finish, _inside
    from musclewrap.scene import load_scene, run_scene
    from musclewrap.solver import _contact

    threadpool_limits(1)
    numba.set_num_threads(1)
    # where the function is looked up when called (the modules that import it by name)
    homes = {
        "bone_vertices_inside": (_inside, [_finish, _contact]),
        "push_out": (_finish, [_contact]),
    }[a.function]
    f = getattr(homes[0], a.function)
    kept: list[tuple[Any, Any]] = []

    def keep(*args: Any, **kw: Any) -> Any:
        kept.append(copy.deepcopy((args, kw), _shared((args, kw))))
        return f(*args, **kw)

    scene = dataclasses.replace(load_scene(a.scene), paper_frames=0)
    for m in homes[1]:
        setattr(m, a.function, keep)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            run_scene(scene, Path(tmp) / "out", frames=a.frames, workers=1, render=False,
                      progress=None, cache_dir=Path(tmp) / "cache")  # fmt: skip
    finally:
        for m in homes[1]:
            setattr(m, a.function, f)
    totals = []
    for _ in range(a.repeats):
        spent = 0.0
        for args, kw in kept:
            args2, kw2 = copy.deepcopy((args, kw), _shared((args, kw)))
            t0 = time.process_time()
            f(*args2, **kw2)
            spent += time.process_time() - t0
        totals.append(spent)
    n = max(len(kept), 1)
    print(f"{a.function}: {len(kept)} calls ({scene.name}, frames {a.frames}); CPU a call "
          f"{1e3 * min(totals) / n:.3f} ms least, {1e3 * statistics.median(totals) / n:.3f} ms "
          f"median over {a.repeats} repeats")  # fmt: skip


if __name__ == "__main__":
    main()

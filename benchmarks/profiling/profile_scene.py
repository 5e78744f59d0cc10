"""Where a scene's time goes: cProfile of a warm run in one process, on one thread.

    python benchmarks/profiling/profile_scene.py [SCENE] [--frames 0:211:1] [--muscle NAME]
        [--no-muscles] [--top 40] [--phases]

Runs the scene once to warm the caches (preparations, bone probes, compiled kernels), then
again under cProfile with ``--workers 1`` and one BLAS and numba thread (as every task runs),
no GIF and no paper comparison, and prints the cumulative table. ``--no-muscles``: muscles
against bones only (`[collisions] muscles = false`); ``--muscle``: that muscle alone.
cProfile slows the Python parts more than the compiled ones: read it for where, not how long.

``--phases``: no cProfile; the timed run with the contact's phases timed by the clock
(ms per muscle-frame, the pose's solve beside them), then the same frames with
``--no-collisions``: what the contact's own work costs a muscle-frame, measured as it runs.

``--calls``: no cProfile; per query of the bones (`Obstacle.bounds`, ``interpolate``,
``query``, ``measure``, ``signed``, ``vertices_near``), how often a muscle-frame calls it,
with how many points, and what a call costs: the contact's queries are many and small.

``--candidates``: no cProfile; per muscle and bone, how many of its vertices each cage step
(after the solve, and in the rounds) takes as candidates (within ``defaults.contact_band`` of the bone's margin),
and per muscle how many steps each call of the bones' contact after the solve takes (and how
often it reaches ``defaults.contact_cage_steps``)
and how many of those are too near (median and most over the steps): how large the contact
is that the steps work on.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import cProfile
import dataclasses
import functools
import pstats
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


#: (module, owner, name, label): what --phases times; a label's calls inside another's count
#: in both (the cage's steps inside the bones' contact and inside a round)
PHASES = (
    ("solver._deformer", "Deformer", "_solve_default", "the pose's solve"),
    ("solver._deformer", None, "Near", "bones: which vertices may be near"),
    ("solver._contact", "ContactSteps", "_cage_contact", "bones: the cage's steps after the solve"),
    ("solver._together", None, "overlaps", "muscles: overlap search, rounds"),
    ("solver._contact", "ContactSteps", "contact_round", "muscles: a round's cage step"),
    ("solver._together", None, "push_apart", "muscles: a round's fine step"),
    ("solver._contact", "ContactSteps", "settle", "bones: the fine finish"),
    ("solver._together", None, "overlap_depths", "muscles: the exact check"),
    ("solver._contact", "ContactSteps", "_cage_step", "  of which cage steps"),
    ("solver._contact", "ContactSteps", "_bone_points", "  of which bones' points"),
)
_CONTACT = PHASES[1:8]


@contextlib.contextmanager
def _timed(acc: dict[str, float], calls: dict[str, int]) -> Iterator[None]:
    """Every function of `PHASES` timed by the clock while inside (put back after)."""
    import importlib

    kept = []
    for module, owner, name, label in PHASES:
        mod = importlib.import_module(f"musclewrap.{module}")
        obj = mod if owner is None else getattr(mod, owner)
        f = getattr(obj, name)

        def timed(*args, _f=f, _label=label, **kw):  # noqa: ANN002, ANN003, ANN202
            t0 = time.perf_counter()
            try:
                return _f(*args, **kw)
            finally:
                acc[_label] += time.perf_counter() - t0
                calls[_label] += 1

        setattr(obj, name, functools.wraps(f)(timed))
        kept.append((obj, name, f))
    try:
        yield
    finally:
        for obj, name, f in kept:
            setattr(obj, name, f)


def phases(scene, frames: str) -> None:  # noqa: ANN001
    """The contact's phases per muscle-frame, by the clock, beside the run without contact."""
    from musclewrap.scene import run_scene

    n = len(scene.muscles) * len(range(*(int(x) for x in frames.split(":"))))
    off = dataclasses.replace(scene, collisions=False, muscle_collisions=False)
    acc: dict[str, float] = collections.defaultdict(float)
    calls: dict[str, int] = collections.defaultdict(int)
    walls = {}
    with tempfile.TemporaryDirectory() as tmp:
        kw = dict(frames=frames, workers=1, render=False, progress=None,
                  cache_dir=Path(tmp) / "cache")  # fmt: skip
        for label, sc in (("contact on", scene), ("--no-collisions", off)):
            run_scene(sc, Path(tmp) / "warm", **kw)
            t0 = time.perf_counter()
            if label == "contact on":
                with _timed(acc, calls):
                    run_scene(sc, Path(tmp) / "on", **kw)
            else:
                run_scene(sc, Path(tmp) / "off", **kw)
            walls[label] = time.perf_counter() - t0
    on, off_s = walls["contact on"], walls["--no-collisions"]
    print(f"{scene.name}: frames {frames}, {n} muscle-frames, one process, one thread, warm")
    print(f"  run with contact {on:.2f} s ({1e3 * on / n:.1f} ms a muscle-frame), "
          f"--no-collisions {off_s:.2f} s ({1e3 * off_s / n:.1f} ms), {on / off_s:.2f}x")  # fmt: skip
    own = sum(acc[label] for *_, label in _CONTACT)
    for *_, label in PHASES:
        print(f"  {label:<42} {1e3 * acc[label] / n:7.2f} ms a muscle-frame ({calls[label]} calls)")
    total = "the contact's own work (the seven above)"
    print(f"  {total:<42} {1e3 * own / n:7.2f} ms a muscle-frame")


def candidates(scene, frames: str) -> None:  # noqa: ANN001
    """Per muscle and bone, the cage steps' candidates and those too near (median, most)."""
    import numpy as np

    from musclewrap.constants import defaults
    from musclewrap.scene import run_scene
    from musclewrap.solver import _contact

    seen: dict[tuple[str, str], list[tuple[int, int]]] = collections.defaultdict(list)
    find, cls = _contact.contact_candidates, _contact.ContactSteps
    kept = {k: getattr(cls, k) for k in ("_cage_contact", "contact_round", "_cage_step")}
    at = [""]  # the muscle whose steps these are (its mesh's name)
    # per muscle, how many cage steps each call of the bones' contact after the solve took
    steps: dict[str, list[int]] = collections.defaultdict(list)
    taken = [0]

    def named(f):  # noqa: ANN001, ANN202
        def call(self, *args, **kw):  # noqa: ANN001, ANN002, ANN003, ANN202
            at[0] = Path(self.muscle.source).stem
            taken[0] += f is kept["_cage_step"]
            return f(self, *args, **kw)

        return call

    def stepped(f):  # noqa: ANN001, ANN202
        def call(self, *args, **kw):  # noqa: ANN001, ANN002, ANN003, ANN202
            taken[0] = 0
            out = named(f)(self, *args, **kw)
            steps[at[0]].append(taken[0])
            return out

        return call

    def counted(P, placed, margin, band, near, sides=None):  # noqa: ANN001, ANN202
        for b, pl in enumerate(placed):
            r = near.within(b, P, band)
            Q = pl.to_obstacle(P[r])
            idx, phi, _ = pl.obstacle.interpolate(Q, margin + band) if len(r) else (r, r, r)
            gap = phi - near.allowed[b][r[idx]]
            seen[at[0], pl.name].append((int((gap < band).sum()), int((gap < 0).sum())))
        return find(P, placed, margin, band, near, sides)

    _contact.contact_candidates = counted
    for k, f in kept.items():
        setattr(cls, k, stepped(f) if k == "_cage_contact" else named(f))
    try:
        with tempfile.TemporaryDirectory() as tmp:
            run_scene(scene, Path(tmp) / "out", frames=frames, workers=1, render=False,
                      progress=None, cache_dir=Path(tmp) / "cache")  # fmt: skip
    finally:
        _contact.contact_candidates = find
        for k, f in kept.items():
            setattr(cls, k, f)
    print(f"{scene.name}: frames {frames}; per cage step, vertices within the band / too near")
    for (name, bone), got in sorted(seen.items()):
        a = np.array(got)
        print(f"  {name:<28} {bone:<12} {len(a):4d} steps, median "
              f"{np.median(a[:, 0]):6.0f} / {np.median(a[:, 1]):4.0f}, most "
              f"{a[:, 0].max():6d} / {a[:, 1].max():4d}")  # fmt: skip
    cap = defaults.contact_cage_steps
    print(f"cage steps a call of the bones' contact after the solve (the cap: {cap})")
    for name, got in sorted(steps.items()):
        n = np.bincount(got, minlength=cap + 1)
        print(f"  {name:<28} {len(got):4d} calls: " + ", ".join(
            f"{k} steps {c}" for k, c in enumerate(n) if c
        ) + f"; at the cap {100 * n[cap:].sum() / len(got):.1f} %")  # fmt: skip


#: what --calls counts: the obstacles' queries, each called with its points first
_QUERIES = ("bounds", "interpolate", "query", "measure", "signed", "vertices_near")


def calls(scene, frames: str) -> None:  # noqa: ANN001
    """Per query of the bones (`Obstacle`'s), calls a muscle-frame, points a call, cost a call.

    The second of two runs (the first warms the caches), one process, one thread. A
    query's own time includes the ones it makes (``query`` calls ``bounds``).
    """
    import numpy as np

    from musclewrap.contact import _obstacle
    from musclewrap.scene import run_scene

    sizes: dict[str, list[int]] = collections.defaultdict(list)
    spent: dict[str, float] = collections.defaultdict(float)
    kept = {k: getattr(_obstacle.Obstacle, k) for k in _QUERIES}

    def timed(name, f):  # noqa: ANN001, ANN202
        def call(self, Q, *args, **kw):  # noqa: ANN001, ANN002, ANN003, ANN202
            t0 = time.perf_counter()
            try:
                return f(self, Q, *args, **kw)
            finally:
                spent[name] += time.perf_counter() - t0
                sizes[name].append(len(Q))

        return call

    n = len(scene.muscles) * len(range(*(int(x) for x in frames.split(":"))))
    with tempfile.TemporaryDirectory() as tmp:
        kw = dict(frames=frames, workers=1, render=False, progress=None,
                  cache_dir=Path(tmp) / "cache")  # fmt: skip
        run_scene(scene, Path(tmp) / "warm", **kw)
        for k, f in kept.items():
            setattr(_obstacle.Obstacle, k, timed(k, f))
        try:
            run_scene(scene, Path(tmp) / "timed", **kw)
        finally:
            for k, f in kept.items():
                setattr(_obstacle.Obstacle, k, f)
    print(f"{scene.name}: frames {frames}, {n} muscle-frames, one process, one thread, warm")
    for k in _QUERIES:
        got = sizes.get(k, [])
        v = np.array(got or [0])
        print(f"  {k:<14} {len(got) / n:6.1f} calls a muscle-frame, points a call "
              f"median {np.median(v):6.0f} mean {v.mean():6.0f}; {1e3 * spent[k] / n:5.2f} ms "
              f"a muscle-frame, {1e6 * spent[k] / max(len(got), 1):5.0f} us a call")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument("--frames", default="0:211:1")
    p.add_argument("--muscle")
    p.add_argument("--no-muscles", action="store_true")
    p.add_argument("--top", type=int, default=40)
    p.add_argument("--phases", action="store_true")
    p.add_argument("--candidates", action="store_true")
    p.add_argument("--calls", action="store_true")
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
    if a.phases:
        phases(scene, a.frames)
        return
    if a.candidates:
        candidates(scene, a.frames)
        return
    if a.calls:
        calls(scene, a.frames)
        return
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

"""The contact's thresholds on either side of their defaults, on the deep squat.

    python benchmarks/tuning/bench_thresholds.py [--only path_step|cage_depth|cage_size|facing|fine|points|reach|softness]

Drives `examples/lhdl_squat.toml` (the OpenCap deep squat, hip flexion to 106 deg) and, per
setting, runs the muscles it matters for with the setting replaced, checks the written meshes
independently (`musclewrap.run.verify_run`: muscle vertex in bone, bone vertex in
muscle) and prints the largest shape change (and on how many frames it exceeds 0.5):

- ``path_step`` (`musclewrap.constants.Defaults.path_step`, the waypoints' spacing): 5, 10
  (default), 20, 45 deg and 200 deg (no waypoint: every frame from the rest pose), frames
  560-760 every 4th (the deepest), gluteus maximus and iliacus;
- ``cage_depth`` (``contact_cage_depth``, where the cage's contact steps hand over to the fine
  finish): 0.5 and 0.25 (default) mean edges, gluteus maximus, frames 700-760;
- ``cage_size`` (the iliacus's cage, `[[muscle]] cage_size`): 300 (the default) and 200
  (`examples/lhdl_*.toml`), the whole squat, checked every 10th frame;
- ``facing`` (``muscle_facing_reach``, the faces of a muscle through which another's vertices
  leave it): 5, 10, 15 (default) and 25 mm, and 1000 mm (every face: the nearest way out), on
  `examples/gait2392_walk.toml`'s worst frames (50, 125, 200; the rectus femoris 14.9 mm into
  the vastus lateralis without muscle contact), every muscle checked against the others;
- ``fine`` (``muscle_fine_depth``, where the muscles' rounds hand over from `nudge` on the
  fine vertices to the next step: `press`'s plate to ``muscle_plate_depth`` with
  ``muscle_fine_plate``, as by default, else the cage): 0 (no `nudge`), 0.25 (default), 0.5 and 1
  mean edges, on `examples/lhdl_walk.toml` every 5th frame, every one checked, with the
  overlap searches per frame (each round one; the cost of the rounds goes with them);
- ``points`` (``contact_points_per_cage_vertex``, another muscle's vertices standing in a muscle
  kept as conditions of its cage step per cage vertex): 1, 3 (default) and every one, on
  `examples/gait2392_walk.toml` every 5th frame, every one checked, with the run's seconds
  (one run each in this process: a rough figure, no repeats);
- ``reach`` (``line_reach``, how far past the muscle a path's tail stays bound, in mean
  thicknesses ``4 V / A``): 0.5, 1 (default), 2, 4 and none (every sample bound), on
  `examples/gait2392_walk.toml`'s semitendinosus through the whole walk with the LHDL sweeps'
  fibres (its fibres' moment arms more than 3 mm from the median of their 5 neighbouring
  frames, shape change, iterations), and per setting what it leaves unbound on every muscle
  of the gait2392 and LHDL walks.

- ``softness`` (``contact_softness``, the regularisation of the cage's contact conditions): 0.1,
  0.2, 0.3, 0.4, 0.5 (default), 0.7 and 1, on the squat's deepest frames (700-740 every 4th,
  every muscle, every frame checked) and on `examples/gait2392_walk.toml` every 10th frame.

Every run is in this process, on one worker (a replaced default does not reach worker
processes); no timing is taken but for ``points``.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _run(scene, muscles, frames, check, cache, **setting):  # noqa: ANN001, ANN003, ANN202
    from musclewrap.constants import defaults
    from musclewrap.run import verify_run
    from musclewrap.scene import run_scene

    sc = dataclasses.replace(
        scene, muscles=tuple(m for m in scene.muscles if m.name in muscles), paper_frames=0
    )
    old = {k: getattr(defaults, k) for k in setting}
    try:
        for k, v in setting.items():
            object.__setattr__(defaults, k, v)
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "o"
            s = run_scene(
                sc, out, frames=frames, workers=1, cache_dir=cache, progress=None, render=False
            )
            checked = verify_run(sc, out, check)
    finally:
        for k, v in old.items():
            object.__setattr__(defaults, k, v)
    return s.rows, checked


def _print(label, muscles, rows, checked, others=False) -> None:  # noqa: ANN001
    for m in muscles:
        q = [r for r in rows if r["muscle"] == m]
        w = [r for r in checked if r["muscle"] == m]
        shape = [r["shape_change_max"] for r in q]
        print(
            f"  {label:<24} {m:<16} muscle vertex in bone <= "
            f"{max(r['muscle_in_bone'] for r in w):5.2f}, bone vertex in muscle <= "
            f"{max(r['bone_in_muscle'] for r in w):5.2f}, "
            + (
                f"in another muscle <= {max(r['muscle_in_muscle'] for r in w):5.2f}, "
                if others
                else ""
            )
            + f"shape change <= {max(shape):.2f} "
            f"({sum(x > 0.5 for x in shape)} of {len(q)} frames over 0.5), unconverged "
            f"{sum(not r['converged'] for r in q)}"
        )


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument(
        "--only",
        choices=(
            "path_step",
            "cage_depth",
            "cage_size",
            "facing",
            "fine",
            "points",
            "reach",
            "softness",
        ),  # fmt: skip
    )
    a = p.parse_args()
    from musclewrap.scene import load_scene

    scene = load_scene(ROOT / "examples" / "lhdl_squat.toml")
    cache = Path(tempfile.mkdtemp()) / "cache"
    print(f"{ROOT / 'examples' / 'lhdl_squat.toml'}: thresholds on either side")
    if a.only in (None, "path_step"):
        mus = ("gluteus_maximus", "iliacus")
        print("path_step (frames 560:760:4, every frame checked)")
        for step in (5.0, 10.0, 20.0, 45.0, 200.0):
            rows, checked = _run(scene, mus, "560:760:4", "560:760:4", cache, path_step=step)
            _print(f"path_step {step:g} deg", mus, rows, checked)
    if a.only in (None, "cage_depth"):
        mus = ("gluteus_maximus",)
        print("contact_cage_depth (frames 700:760:1, every frame checked)")
        for depth in (0.5, 0.25):
            rows, checked = _run(
                scene, mus, "700:760:1", "700:760:1", cache, contact_cage_depth=depth
            )
            _print(f"contact_cage_depth {depth:g}", mus, rows, checked)
    if a.only in (None, "cage_size"):
        print("iliacus cage_size (frames 0:801:1, every 10th checked)")
        for size in (300, 200):
            sc = dataclasses.replace(
                scene,
                muscles=tuple(
                    dataclasses.replace(m, cage_size=size) if m.name == "iliacus" else m
                    for m in scene.muscles
                ),
            )
            rows, checked = _run(sc, ("iliacus",), "0:801:1", "0:801:10", cache)
            _print(f"cage_size {size}", ("iliacus",), rows, checked)
    if a.only in (None, "facing"):
        gait = load_scene(ROOT / "examples" / "gait2392_walk.toml")
        names = tuple(m.name for m in gait.muscles)
        print("muscle_facing_reach (gait2392 walk, frames 50:201:75, every frame checked)")
        for reach in (5.0, 10.0, 15.0, 25.0, 1000.0):
            rows, checked = _run(
                gait, names, "50:201:75", "50:201:75", cache, muscle_facing_reach=reach
            )
            _print(f"facing {reach:g} mm", names, rows, checked, others=True)
    if a.only in (None, "fine"):
        import musclewrap.solver._together as together

        walk = load_scene(ROOT / "examples" / "lhdl_walk.toml")
        names = tuple(m.name for m in walk.muscles)
        calls = [0]
        search = together.overlaps

        def counted(*args):  # noqa: ANN002, ANN202
            calls[0] += 1
            return search(*args)

        together.overlaps = counted
        print("muscle_fine_depth (LHDL walk, frames 0:211:5, every frame checked)")
        try:
            for depth in (0.0, 0.25, 0.5, 1.0):
                calls[0] = 0
                rows, checked = _run(
                    walk, names, "0:211:5", "0:211:5", cache, muscle_fine_depth=depth
                )
                print(f"  {calls[0] / (len(rows) / len(names)):.1f} overlap searches a frame")
                _print(f"fine {depth:g} edges", names, rows, checked, others=True)
        finally:
            together.overlaps = search
    if a.only in (None, "points"):
        import time

        gait = load_scene(ROOT / "examples" / "gait2392_walk.toml")
        names = tuple(m.name for m in gait.muscles)
        print("contact_points_per_cage_vertex (gait2392 walk, frames 0:211:5, every one checked)")
        _run(gait, names, "0:10:5", "0:10:5", cache)  # the preparations, cached
        for k in (1, 3, 10**9):
            t0 = time.perf_counter()
            rows, checked = _run(
                gait, names, "0:211:5", "0:211:5", cache, contact_points_per_cage_vertex=k
            )
            print(f"  {time.perf_counter() - t0:.1f} s (run and check)")
            _print(f"points {k if k < 10**9 else 'all'}", names, rows, checked, others=True)

    if a.only in (None, "reach"):
        _reach(cache)
    if a.only in (None, "softness"):
        names = tuple(m.name for m in scene.muscles)
        gait = load_scene(ROOT / "examples" / "gait2392_walk.toml")
        gnames = tuple(m.name for m in gait.muscles)
        print("contact_softness (squat frames 700:741:4 and gait2392 walk 0:211:10, all checked)")
        for soft in (0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0):
            rows, checked = _run(
                scene, names, "700:741:4", "700:741:4", cache, contact_softness=soft
            )
            _print(f"softness {soft:g}, squat", names, rows, checked, others=True)
            rows, checked = _run(gait, gnames, "0:211:10", "0:211:10", cache, contact_softness=soft)
            _print(f"softness {soft:g}, gait2392", gnames, rows, checked, others=True)


def _reach(cache: Path) -> None:
    """``line_reach`` on either side of its default (the module's docstring)."""
    from bench_moment_arms import _spikes  # the same count as its --smoothness

    import musclewrap.solver._deformer as solver
    from musclewrap.constants import defaults
    from musclewrap.scene import load_scene, run_scene

    gait = load_scene(ROOT / "examples" / "gait2392_walk.toml")
    fibres = load_scene(ROOT / "examples" / "lhdl_hip_sweeps.toml").fibres
    semi = dataclasses.replace(
        gait,
        muscles=tuple(m for m in gait.muscles if m.name == "semitendinosus"),
        fibres=fibres,
        gif=False,
    )
    walks = [gait, load_scene(ROOT / "examples" / "lhdl_walk.toml")]
    print("line_reach (gait2392 walk's semitendinosus, frames 0:211:1, sweeps' fibres)")
    old = defaults.line_reach
    bound: list[object] = []
    bind = solver.Deformer.__init__

    def kept(self, muscle, rest_lines, **kw):  # noqa: ANN001, ANN003, ANN202
        bind(self, muscle, rest_lines, **kw)
        bound.append(self)

    try:
        for reach in (0.5, 1.0, 2.0, 4.0, None):
            object.__setattr__(defaults, "line_reach", reach)
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "o"
                s = run_scene(semi, out, workers=1, cache_dir=cache, progress=None, render=False)
                # per coordinate: (off, fibre-frames, largest, ...) of the semitendinosus
                got = [_spikes(out / "fibres.csv", c, largest=True)["semitendinosus"]
                       for c in fibres.moment_arms]  # fmt: skip
            off, n = sum(g[0] for g in got), sum(g[1] for g in got)
            worst = max(g[2] for g in got)
            print(
                f"  reach {reach!s:<5} semitendinosus: {off} of {n} fibre-frames > 3 mm off "
                f"(largest {worst:.1f} mm), shape change <= "
                f"{max(r['shape_change_max'] for r in s.rows):.2f}, iterations <= "
                f"{max(r['iterations'] for r in s.rows)}, unconverged "
                f"{sum(not r['converged'] for r in s.rows)}"
            )
            solver.Deformer.__init__ = kept
            try:
                for sc in walks:
                    bound.clear()
                    with tempfile.TemporaryDirectory() as tmp:
                        one = dataclasses.replace(sc, fibres=None, gif=False, paper_frames=0)
                        run_scene(one, Path(tmp), frames="0:1", workers=1, cache_dir=cache,
                                  progress=None, render=False)  # fmt: skip
                    cut = {k: v for d in bound for k, v in d.unbound.items()}
                    print(
                        f"    {sc.path.name}: unbound "
                        + (
                            ", ".join(
                                f"{k} {100 * (a + b):.0f} %" for k, (a, b, _) in sorted(cut.items())
                            )
                            or "nothing"
                        )
                    )
            finally:
                solver.Deformer.__init__ = bind
    finally:
        object.__setattr__(defaults, "line_reach", old)


if __name__ == "__main__":
    main()

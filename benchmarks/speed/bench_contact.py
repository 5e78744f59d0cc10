"""Contact with bones on a whole scene: time with and without, and the independent check.

    python benchmarks/speed/bench_contact.py [SCENE] [--frames 0:211:1] [--check-every 10] [--no-timing]
        [--motion MOT [--negate COORDINATE ...]]

Runs the scene warm (preparations cached by a first run) with contact on and with
``--no-collisions``, alternately, three times each (over ``--frames``, default 0:211:1), and
prints the medians and their ratio;
then checks the written meshes of the contact run against the full-resolution bones
(`musclewrap.run.verify_run`: exact winding numbers and distances) on every
``--check-every``-th frame. ``--no-timing``: one run with contact over ``--frames`` (default
every frame), then the check (a scene with several motions, such as the sweeps, is checked
motion by motion over all its frames, or over ``--frames`` of each).
``--motion``: the scene driven by another motion instead (with ``--no-timing``; run here on
2 workers); ``--negate``: coordinates of it negated first, for a motion recorded on a model
whose sign for them is the other (OpenCap's knee_angle_r is flexion positive, gait2392's
negative).

``--compare CHECKOUT ...``: the timing only, of this checkout and each other one (a folder
holding a ``src/musclewrap``, e.g. a ``git worktree`` of the parent commit) in turns, in one
sitting (the host's speed drifts between sittings): per checkout the median with contact,
with ``--no-collisions`` and their ratio, and whether its meshes and report values (less
the timings) are the same bytes as this checkout's.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def _run(
    scene: str, out: Path, frames: str, extra: list[str], checkout: Path | None = None
) -> float:
    """Wall seconds of one run (``checkout``: another checkout's package)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the shared helpers
    from _common import timed_run

    return timed_run(scene, out, ["--no-gif", "--frames", frames, *extra], checkout)


def _same_outputs(a: Path, b: Path) -> str:
    """Whether two run folders hold the same meshes, byte for byte, and report values."""
    meshes = sorted(p.relative_to(a) for p in a.rglob("*.vt[pk]"))
    differ = [p for p in meshes if (a / p).read_bytes() != (b / p).read_bytes()]

    def values(folder: Path) -> list[dict]:
        with open(folder / "report.csv", newline="") as fh:
            return [
                {k: v for k, v in row.items() if "second" not in k} for row in csv.DictReader(fh)
            ]

    same = values(a) == values(b)
    return (
        f"{len(meshes) - len(differ)} of {len(meshes)} meshes the same bytes, report values "
        f"{'the same' if same else 'DIFFER'}"
    )


def compare(scene: str, frames: str, repeats: int, checkouts: list[Path]) -> None:
    """Each checkout's runs with and without contact in turns, and their outputs."""
    import os

    subjects: list[tuple[str, Path | None]] = [("this checkout", None)]
    subjects += [(str(c), c.resolve()) for c in checkouts]
    times: dict[str, tuple[list[float], list[float]]] = {n: ([], []) for n, _ in subjects}
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, c) in enumerate(subjects):  # warm each one's caches and kernels
            _run(scene, Path(tmp) / f"on{i}", frames, [], c)
            _run(scene, Path(tmp) / f"off{i}", frames, ["--no-collisions"], c)
        for _ in range(repeats):
            for i, (name, c) in enumerate(subjects):
                times[name][0].append(_run(scene, Path(tmp) / f"on{i}", frames, [], c))
                times[name][1].append(
                    _run(scene, Path(tmp) / f"off{i}", frames, ["--no-collisions"], c)
                )
        print(
            f"{scene} frames {frames}, warm, no GIF, {repeats} runs each, in turns "
            f"({os.cpu_count()} CPUs)"
        )
        for i, (name, _) in enumerate(subjects):
            on, off = (float(np.median(t)) for t in times[name])
            same = "" if i == 0 else "; " + _same_outputs(Path(tmp) / "on0", Path(tmp) / f"on{i}")
            print(
                f"  {name}: contact on {on:.1f} s, --no-collisions {off:.1f} s, "
                f"{on / off:.2f}x{same}"
            )


def _other(rows: list[dict]) -> str:
    """The deepest vertex of a muscle in another one over the checked frames, and where."""
    worst = max(rows, key=lambda x: x["muscle_in_muscle"])
    if not worst["muscle_in_muscle"]:
        return " 0.000"
    return (
        f"{worst['muscle_in_muscle']:6.3f} ({worst['muscle_in_muscle_other']}, frame "
        f"{worst['frame']}, up to {max(x['muscle_in_muscle_vertices'] for x in rows)} vertices a frame)"
    )


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_walk.toml"))
    p.add_argument(
        "--frames",
        default=None,
        help="the frames run (default: 0:211:1 for the timing, every frame with --no-timing)",
    )
    p.add_argument("--keep", type=Path, default=None, help="--no-timing: write the run here")
    p.add_argument("--check-every", type=int, default=10)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-timing", action="store_true")
    p.add_argument("--motion", default=None)
    p.add_argument("--negate", nargs="*", default=[])
    p.add_argument("--compare", nargs="+", type=Path, metavar="CHECKOUT")
    a = p.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the shared helpers
    from _common import most, negated_motion

    walk_frames = a.frames or "0:211:1"
    if a.compare:
        compare(a.scene, walk_frames, a.repeats, a.compare)
        return
    import dataclasses

    from musclewrap.constants import defaults
    from musclewrap.run import verify_run
    from musclewrap.scene import load_scene, read_motion

    if a.no_timing:
        scene = load_scene(a.scene)
        with tempfile.TemporaryDirectory() as tmp:
            out = a.keep or Path(tmp) / "on"
            t0 = time.perf_counter()
            if a.motion is not None:
                from musclewrap.scene import run_scene

                path = negated_motion(a.motion, a.negate, Path(tmp))
                scene = dataclasses.replace(scene, motions=(path,), gif=False)
                run_scene(scene, out, workers=2, progress=None, frames=a.frames)
            else:
                cmd = [sys.executable, "-m", "musclewrap.cli", "run", a.scene, "-o", str(out)]
                if a.frames is not None:
                    cmd += ["--frames", a.frames]
                subprocess.run(
                    [*cmd, "--no-gif", "--allow-unconverged"], check=True, capture_output=True
                )
            wall = time.perf_counter() - t0
            for m in scene.motions:
                sc = dataclasses.replace(scene, motions=(m,))
                folder = out if len(scene.motions) == 1 else out / m.stem
                n = read_motion(m).n_frames
                start, stop, step = 0, n, 1
                if a.frames is not None:
                    start, stop, *rest = (int(x) for x in a.frames.split(":"))
                    step = rest[0] if rest else 1
                rows = verify_run(sc, folder, f"{start}:{min(stop, n)}:{step * a.check_every}")
                with open(folder / "report.csv", newline="") as fh:
                    rep = list(csv.DictReader(fh))
                rounds: dict[str, int] = {}
                for x in rep:
                    rounds[x["frame"]] = int(float(x.get("muscle_rounds") or 0))
                r_all = sorted(rounds.values())
                cap = sum(r >= defaults.muscle_rounds for r in r_all)
                print(
                    f"{m.stem}: {len(rounds)} frames run in {wall:.0f} s (2 workers); rounds a "
                    f"frame median {r_all[len(r_all) // 2]}, most {r_all[-1]}, at the cap "
                    f"({defaults.muscle_rounds}) on {cap}; independent check "
                    f"on {len(rows) // len(scene.muscles)} frames"
                )
                for mu in scene.muscles:
                    r = [x for x in rows if x["muscle"] == mu.name]
                    q = [x for x in rep if x["muscle"] == mu.name]
                    print(
                        f"    {mu.name:<18} muscle vertex in bone <= "
                        f"{max(x['muscle_in_bone'] for x in r):6.3f}, bone vertex in muscle <= "
                        f"{max(x['bone_in_muscle'] for x in r):6.3f}, in another muscle <= "
                        f"{_other(r)}; all frames: in another muscle <= "
                        f"{max(float(x.get('muscle_overlap_max') or 'nan') for x in q):.3f}, "
                        "shape change <= "
                        f"{max(float(x['shape_change_max']) for x in q):.3f} (frames over "
                        f"0.5: {sum(float(x['shape_change_max']) > 0.5 for x in q)}), fit <= "
                        f"{max(float(x['skeleton_fit_mean']) for x in q):.2f}, where the lines "
                        f"are free <= {most(q, 'skeleton_fit_free'):.2f}, unconverged "
                        f"{sum(x['converged'] != 'True' for x in q)}"
                    )
        return

    with tempfile.TemporaryDirectory() as tmp:
        on, off = Path(tmp) / "on", Path(tmp) / "off"
        _run(a.scene, on, walk_frames, [])  # warm the cache
        _run(a.scene, off, walk_frames, ["--no-collisions"])
        t_on, t_off = [], []
        for _ in range(a.repeats):
            t_on.append(_run(a.scene, on, walk_frames, []))
            t_off.append(_run(a.scene, off, walk_frames, ["--no-collisions"]))
        m_on, m_off = float(np.median(t_on)), float(np.median(t_off))
        print(f"{a.scene} frames {walk_frames}, warm, no GIF, {a.repeats} runs each, alternating")
        print(
            f"  contact on: median {m_on:.1f} s; --no-collisions: {m_off:.1f} s; {m_on / m_off:.2f}x"
        )
        scene = load_scene(a.scene)
        start, stop, *step = (int(x) for x in walk_frames.split(":"))
        step = (step[0] if step else 1) * a.check_every
        for label, out in (("contact on", on), ("--no-collisions", off)):
            rows = verify_run(scene, out, f"{start}:{stop}:{step}")
            print(f"  {label}: independent check on {len(rows) // len(scene.muscles)} frames")
            for m in scene.muscles:
                r = [x for x in rows if x["muscle"] == m.name]
                print(
                    f"    {m.name:<18} muscle vertex in bone <= "
                    f"{max(x['muscle_in_bone'] for x in r):6.3f}, bone vertex in muscle <= "
                    f"{max(x['bone_in_muscle'] for x in r):6.3f}, in another muscle <= "
                    f"{_other(r)}"
                )


if __name__ == "__main__":
    main()

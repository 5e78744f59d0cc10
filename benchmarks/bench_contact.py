"""Contact with bones on a whole scene: time with and without, and the independent check.

    python benchmarks/bench_contact.py [SCENE] [--frames 0:211:1] [--check-every 10] [--no-timing]
        [--motion MOT [--negate COORDINATE ...]]

Runs the scene warm (preparations cached by a first run) with contact on and with
``--no-collisions``, alternately, three times each, and prints the medians and their ratio;
then checks the written meshes of the contact run against the full-resolution bones
(`musclewrap.scene._verify.verify_run`: exact winding numbers and distances) on every
``--check-every``-th frame. ``--no-timing``: one run with contact, then the check (a scene
with several motions, such as the sweeps, is checked motion by motion over all its frames).
``--motion``: the scene driven by another motion instead (with ``--no-timing``; run here on
2 workers); ``--negate``: coordinates of it negated first, for a motion recorded on a model
whose sign for them is the other (OpenCap's knee_angle_r is flexion positive, gait2392's
negative).
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _run(scene: str, out: Path, frames: str, extra: list[str]) -> float:
    from musclewrap._bench import timed_run

    return timed_run(scene, out, ["--no-gif", "--frames", frames, *extra])


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
    p.add_argument("--frames", default="0:211:1")
    p.add_argument("--check-every", type=int, default=10)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-timing", action="store_true")
    p.add_argument("--motion", default=None)
    p.add_argument("--negate", nargs="*", default=[])
    a = p.parse_args()
    import dataclasses

    from musclewrap.scene import load_scene, read_motion
    from musclewrap.scene._verify import verify_run

    if a.no_timing:
        scene = load_scene(a.scene)
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "on"
            if a.motion is not None:
                from musclewrap.scene import run_scene, write_motion

                mot = read_motion(a.motion)
                cols = {k: (-v if k in a.negate else v) for k, v in mot.columns.items()}
                path = Path(tmp) / Path(a.motion).name
                write_motion(path, mot.time, cols, in_degrees=mot.in_degrees)
                scene = dataclasses.replace(scene, motions=(path,), gif=False)
                run_scene(scene, out, workers=2, progress=None)
            else:
                cmd = [sys.executable, "-m", "musclewrap.cli", "run", a.scene, "-o", str(out)]
                subprocess.run(
                    [*cmd, "--no-gif", "--allow-unconverged"], check=True, capture_output=True
                )
            for m in scene.motions:
                sc = dataclasses.replace(scene, motions=(m,))
                folder = out if len(scene.motions) == 1 else out / m.stem
                n = read_motion(m).n_frames
                rows = verify_run(sc, folder, f"0:{n}:{a.check_every}")
                with open(folder / "report.csv", newline="") as fh:
                    rep = list(csv.DictReader(fh))
                print(f"{m.stem}: independent check on {len(rows) // len(scene.muscles)} frames")
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
                        f"{max(float(x['shape_change_max']) for x in q):.3f}, fit <= "
                        f"{max(float(x['skeleton_fit_mean']) for x in q):.2f}, unconverged "
                        f"{sum(x['converged'] != 'True' for x in q)}"
                    )
        return

    with tempfile.TemporaryDirectory() as tmp:
        on, off = Path(tmp) / "on", Path(tmp) / "off"
        _run(a.scene, on, a.frames, [])  # warm the cache
        _run(a.scene, off, a.frames, ["--no-collisions"])
        t_on, t_off = [], []
        for _ in range(a.repeats):
            t_on.append(_run(a.scene, on, a.frames, []))
            t_off.append(_run(a.scene, off, a.frames, ["--no-collisions"]))
        m_on, m_off = float(np.median(t_on)), float(np.median(t_off))
        print(f"{a.scene} frames {a.frames}, warm, no GIF, {a.repeats} runs each, alternating")
        print(
            f"  contact on: median {m_on:.1f} s; --no-collisions: {m_off:.1f} s; {m_on / m_off:.2f}x"
        )
        scene = load_scene(a.scene)
        start, stop, *step = (int(x) for x in a.frames.split(":"))
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

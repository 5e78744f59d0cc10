"""The demo's scene at other wrap margins and flexions: what the contact does on either side.

    python benchmarks/speed/bench_demo.py [--margins 3 9.1] [--flexions 90 120] [--frames 61]

For each margin of the wrap cylinder over the condyles (mm; the demo's is 3) and each
largest flexion (deg; the demo's 90), writes the demo's scene
(`musclewrap.synthetic.write_knee_scene`), runs it warm (a second run, the preparations
cached; 2 workers, no pictures) and prints, over every frame and both muscles: the deepest
muscle vertex in a bone before the contact and after, the deepest vertex in the other
muscle, the largest shape change, skeleton fit and volume error, unconverged frames, and the
run's seconds.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))


def main() -> None:
    from musclewrap.scene import load_scene, run_scene
    from musclewrap.synthetic import write_knee_scene

    p = argparse.ArgumentParser()
    p.add_argument("--margins", type=float, nargs="+", default=[3.0, 9.1])
    p.add_argument("--flexions", type=float, nargs="+", default=[90.0, 120.0])
    p.add_argument("--frames", type=int, default=61)
    a = p.parse_args()
    print(
        "margin mm | flexion deg | in bone before | after | in muscle | shape | fit mm | "
        "volume | unconverged | s"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for margin in a.margins:
            for flexion in a.flexions:
                folder = Path(tmp) / f"m{margin:g}_f{flexion:g}"
                scene = load_scene(write_knee_scene(folder, a.frames, flexion, margin))
                for run in range(2):  # the second warm
                    s = run_scene(
                        scene, folder / f"out{run}", workers=2, cache_dir=Path(tmp) / "cache",
                        progress=None, render=False,
                    )  # fmt: skip
                rows = s.rows

                def worst(key: str, rows: list = rows) -> float:
                    return max(abs(float(r[key])) for r in rows)

                print(
                    f"{margin:g} | {flexion:g} | {worst('penetration_depth_before'):.3g} | "
                    f"{worst('penetration_depth_max'):.3g} | {worst('muscle_overlap_max'):.3g} | "
                    f"{worst('shape_change_max'):.3g} | {worst('skeleton_fit_mean'):.3g} | "
                    f"{worst('relative_volume_error'):.2g} | {s.unconverged} | {s.seconds:.1f}"
                )


if __name__ == "__main__":
    main()

"""The anchors' weight on either side of its default: largest shape change per muscle and sweep.

Runs the LHDL hip sweeps (contact on, every frame) in this process once per weight and
prints, per motion and muscle, the largest shape change (mean edge lengths) and the
largest mean skeleton fit. In one process (``workers=1``) so that the changed default
reaches the solve: slower than a scene run.

    python benchmarks/tuning/bench_anchor_weight.py [--weights 0.5,0.7,1] [SCENE]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    from musclewrap.constants import defaults
    from musclewrap.scene import load_scene, run_scene

    p = argparse.ArgumentParser()
    p.add_argument("scene", nargs="?", default=str(ROOT / "examples" / "lhdl_hip_sweeps.toml"))
    p.add_argument("--weights", default="0.5,0.7,1")
    a = p.parse_args()
    weights = [float(w) for w in a.weights.split(",")]
    scene = load_scene(Path(a.scene))
    table: dict[tuple[str, str], list[str]] = {}
    for w in weights:
        object.__setattr__(defaults, "anchor_weight", w)
        for mot in scene.motions:
            one = dataclasses.replace(scene, motions=(mot,))
            with tempfile.TemporaryDirectory() as tmp:
                s = run_scene(one, Path(tmp), workers=1, progress=None, render=False)
            for m in scene.muscles:
                rows = [r for r in s.rows if r["muscle"] == m.name]
                shape = max(r["shape_change_max"] for r in rows)
                fit = max(r["skeleton_fit_mean"] for r in rows)
                ok = all(r["converged"] for r in rows)
                cell = f"{shape:.3f} / {fit:.2f}" + ("" if ok else " (unconverged)")
                table.setdefault((Path(mot).stem, m.name), []).append(cell)
    print(f"{a.scene}: largest shape change (mean edges) / skeleton fit mean (mm), per weight")
    print(f"{'motion':16s} {'muscle':18s} " + " ".join(f"{w:>16g}" for w in weights))
    for (mot, m), cells in table.items():
        print(f"{mot:16s} {m:18s} " + " ".join(f"{c:>16s}" for c in cells))


if __name__ == "__main__":
    main()
